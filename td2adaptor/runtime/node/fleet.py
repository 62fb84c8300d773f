"""The robots one edge-node process serves, and the one place that changes that list while it runs.

A robot joins (`add`: its port on the ROS graph, its engine connected, its TD published and registered) or
leaves (`remove`: its engine stopped with every mission in flight ended by a terminal event, its TD cleared
and deregistered, its status `offline`, its port closed) on its own: the other robots keep their bus
connections, their ports and their missions. A robot whose settings changed restarts alone (`replace`).
`apply` takes a whole new list of one origin (a reloaded fleet file), changing only what differs.

Who asks: the fleet file at start and on reload (origin "file"), discovery ("discovery", runtime/node/
graphwatch.py) and admin requests on the bus ("admin", runtime/node/admin.py). Each origin manages its own
robots: a reloaded file never removes a robot discovery found. One change runs at a time (a lock); hooks
(`on_added`, `on_removed`) hear of each robot that started or stopped, after the fact. A shared fleet (share.py)
starts robots with `join` instead, whose slow part (the robots' ROS side, their bus connections) runs outside the
lock: a set of robots starts while another one's start is under way, and robots leave meanwhile.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial

from td2adaptor.model import Model
from td2adaptor.runtime.bus.localbus import LocalBroker
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.node.app import serve
from td2adaptor.runtime.node.claims import check_fleet
from td2adaptor.runtime.node.roslink import RosLink
from td2adaptor.runtime.ros.port import RobotPort

log = logging.getLogger("td2adaptor.runtime.fleet")
#: why a robot is not started: its start (`join`) or its stop (`remove`) is under way on another thread
STARTING_OR_STOPPING = "starting or stopping already"
#: seconds a stopping process waits, for all its robots together, for what is still in flight (calls, the
#: offline status's acknowledgement)
STOP_TIMEOUT = 5.0
#: robots that join together start on this many threads at most (`Fleet._serve_all`), which end with the start
STARTS_AT_ONCE = 8

ORIGINS = ("file", "discovery", "admin")


class FleetError(Exception):
    """A change of the fleet was refused or failed; the message says which robot and why (`why` alone)."""

    def __init__(self, robots: str, why: str) -> None:
        super().__init__(f"robot {robots}: {why}" if robots else why)
        self.why = why


@dataclass
class Changes:
    """What one `apply` did, by robot id; `failed` maps a robot to why it could not be started."""

    added: list[str] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    replaced: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    #: a shared fleet's (share.py): the robots this process lists now, or no longer, that the share gives out
    #: (or retires) a moment later, not in this change: said so, where the log said "no change"
    listed: list[str] = field(default_factory=list)
    unlisted: list[str] = field(default_factory=list)

    def __bool__(self) -> bool:
        return bool(self.added or self.removed or self.replaced or self.failed)

    def describe(self) -> str:
        parts = [f"{what} {', '.join(ids)}" for what, ids in self._parts() if ids]
        parts += [f"{robot} not started ({why})" for robot, why in self.failed.items()]
        if self.listed:
            parts.append(f"lists {', '.join(self.listed)} now (the shared fleet gives each to one of its processes)")
        if self.unlisted:
            parts.append(f"no longer lists {', '.join(self.unlisted)} (retired once no process of the fleet lists it)")
        return "; ".join(parts) or "no change"

    def _parts(self) -> list[tuple[str, list[str]]]:
        return [("added", self.added), ("removed", self.removed), ("restarted", self.replaced)]


def retire_words(robot: str, why: str) -> str:
    """The message of the terminal event of a mission in flight when its robot leaves the fleet."""
    return f"robot {robot} {why}: this edge node no longer follows the mission (the robot may still carry it out)"


class Fleet:
    """The robots of one process (see the module docstring). `link` is the process's ROS link; each robot
    that joins later gets its port from `link.grow`."""

    def __init__(
        self,
        model: Model,
        link: RosLink,
        *,
        distro: str,
        broker: LocalBroker | None = None,
        on_halt: Callable[[str, str], None] | None = None,
    ) -> None:
        self.model = model
        self.link = link
        self.distro = distro
        self.broker = broker
        self.on_halt = on_halt  # (robot, why): a robot's bus stopped serving its broker
        self.on_added: list[Callable[[Engine], None]] = []  # a robot started serving (hooks: presence, metrics)
        self.on_removed: list[Callable[[str], None]] = []  # a robot stopped serving (its id)
        #: the check before robots join: none another live process serves (raises `OwnerConflict`); a shared
        #: fleet (node/share.py) decides that from the members and statuses it follows instead
        self.check: Callable[[Sequence[RuntimeConfig]], None] = partial(check_fleet, model)
        self.prepare: Callable[[Engine], None] | None = None  # each engine, before it serves (share.py)
        #: the last look before a robot connects (its ROS side is up, its session not taken yet): why it must not
        #: be served now, or None. A shared fleet (share.py) declines a robot another member claimed meanwhile
        self.admit: Callable[[RuntimeConfig], str | None] | None = None
        #: how the log names where a robot that joins came from (a shared fleet keeps its robots under one origin
        #: here and knows the real one: file, discovery or admin)
        self.source: Callable[[str, str], str] = lambda _robot, origin: origin
        self._lock = threading.RLock()
        self._engines: dict[str, Engine] = {}
        self._origin: dict[str, str] = {}
        self._links: dict[str, RosLink] = {}  # the grown link of a robot that joined at run time
        self._pending: set[str] = set()  # robots a `join` starts or `remove` stops: not started again meanwhile
        self._closed = False

    # -- reading -------------------------------------------------------------------------------------------

    def engines(self) -> list[Engine]:
        with self._lock:
            return list(self._engines.values())

    def robots(self, origin: str | None = None) -> dict[str, RuntimeConfig]:
        """The configuration of each robot served (of one origin), by id. Read without the fleet's lock, which a
        start holds for seconds on a loaded machine: a shared fleet's member record (what its discovery sees) and
        discovery's looks waited for the end of a start of other robots (issue 32). Each copy is taken at once
        (the GIL), so a robot joining or leaving meanwhile is either in it or not."""
        engines, origins = dict(self._engines), dict(self._origin)
        return {r: e.config for r, e in engines.items() if origin is None or origins.get(r) == origin}

    def origin(self, robot: str) -> str | None:
        return self._origin.get(robot)  # without the lock, as `robots`

    # -- changing ------------------------------------------------------------------------------------------

    def start(self, configs: Sequence[RuntimeConfig], origin: str = "file") -> None:
        """Serve the robots whose ports `link` has already (the start of the process): all or none."""
        with self._lock:
            try:
                for config in configs:
                    self._serve(config, self.link.ports[config.robot], origin)
            except BaseException:
                for robot in list(self._engines):
                    self._engines.pop(robot).stop()
                raise

    def add(self, config: RuntimeConfig, origin: str) -> Engine:
        """Start serving one more robot; raises `FleetError` when it is served already or cannot start (then
        nothing of it is left)."""
        with self._lock:
            self._check_open()
            busy = self._busy(config.robot)
            if busy is not None:
                raise FleetError(config.robot, busy)
            return self._grow([config], origin)[config.robot]

    def remove(self, robot: str, why: str = "was removed from the edge node's fleet", *, retire: bool = True) -> bool:
        """Stop serving `robot` (see the module docstring); False when it was not served. `retire=False`: its
        missions in flight are left to the next owner of the robot (a hand-over, share.py), as at a stop. The stop
        (its last status acknowledged, its port closed: seconds on a loaded machine) runs outside the fleet's lock,
        so a `join` of other robots meanwhile does not wait for it; the robot is not started again until it ended."""
        with self._lock:
            engine = self._engines.pop(robot, None)
            if engine is None:
                return False
            self._origin.pop(robot, None)
            self._pending.add(robot)  # leaving (`join`)
        try:
            try:
                engine.stop(retire=retire_words(robot, why) if retire else None)
            finally:
                self._release(robot)
        finally:
            with self._lock:
                self._pending.discard(robot)
        log.info("robot %s: no longer served (%s)", robot, why)
        self._tell(self.on_removed, robot)
        return True

    def replace(self, config: RuntimeConfig, origin: str) -> Engine:
        """Restart one robot with new settings (the others are not touched)."""
        with self._lock:
            self.remove(config.robot, "restarts with changed settings")
            return self.add(config, origin)

    def apply(self, configs: Sequence[RuntimeConfig], origin: str) -> Changes:
        """Make the robots of `origin` be `configs`: the ones gone leave, the changed ones restart, the new
        ones join (together, on one ROS node). A robot that cannot start is reported in `Changes.failed`; the
        others are served all the same. A robot served from another origin is left as it is."""
        changes = Changes()
        with self._lock:
            self._check_open()
            mine = self.robots(origin)
            wanted = {c.robot: c for c in configs}
            for robot in mine:
                if robot not in wanted:
                    self.remove(robot)
                    changes.removed.append(robot)
            fresh: list[RuntimeConfig] = []
            for robot, config in wanted.items():
                other = self._origin.get(robot)
                if other is not None and other != origin:
                    changes.failed[robot] = f"served already (its {other})"
                elif robot in self._pending:  # its stop (`remove`) is under way on another thread
                    changes.failed[robot] = STARTING_OR_STOPPING
                elif robot not in mine:
                    fresh.append(config)
                elif mine[robot] != config:
                    self.remove(robot, "restarts with changed settings")
                    fresh.append(config)
                    changes.replaced.append(robot)
            started = self._start_all(fresh, origin, changes.failed)
            changes.added += [r for r in started if r not in changes.replaced]
            changes.replaced = [r for r in changes.replaced if r in started]
        return changes

    def join(self, configs: Sequence[RuntimeConfig], origin: str) -> Changes:
        """Start `configs` (together, on one ROS node, as `apply`), with the fleet's lock held only to note them
        and to register each engine: a shared fleet starts a set of robots while an earlier set's start is under
        way, and lets robots go meanwhile (issue 32: a robot claimed during a start of others waited 0.2-1 s for
        its end). A robot served or being started already is not started again (`Changes.failed`); nothing else
        is touched."""
        changes = Changes()
        with self._lock:
            self._check_open()
            fresh: list[RuntimeConfig] = []
            for config in configs:
                busy = self._busy(config.robot)
                if busy is not None:
                    changes.failed[config.robot] = busy
                else:
                    fresh.append(config)
            self._pending.update(c.robot for c in fresh)
        try:
            changes.added += self._start_all(fresh, origin, changes.failed)
        finally:
            with self._lock:
                self._pending.difference_update(c.robot for c in fresh)
        return changes

    def _busy(self, robot: str) -> str | None:
        """(under the lock) Why `robot` cannot be started now: served, or started or stopped by another thread (a
        `join`, a `remove`); None when it can."""
        if robot in self._engines:
            return "served already"
        return STARTING_OR_STOPPING if robot in self._pending else None

    def stop(self) -> None:
        """The process stops: every robot goes offline (missions left to the robot, followed again by the next
        run, ledger.py), then the ports close. No change is taken afterwards."""
        with self._lock:
            self._closed = True
            engines, self._engines = dict(self._engines), {}
            deadline = time.monotonic() + STOP_TIMEOUT  # one bound for the fleet, not one per robot
            for engine in engines.values():
                engine.stop(max(0.1, deadline - time.monotonic()))
            for robot in engines:
                self._release(robot)
            self._origin.clear()

    # -- inside --------------------------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise FleetError("", "the edge node is stopping")

    def _start_all(self, configs: Sequence[RuntimeConfig], origin: str, failed: dict[str, str]) -> list[str]:
        """Start `configs` on one grown link; when that fails, one by one, so that one robot that cannot start
        keeps none of the others from starting."""
        if not configs:
            return []
        try:
            return list(self._grow(configs, origin, failed))
        except FleetError as exc:
            if len(configs) == 1:
                failed[configs[0].robot] = exc.why
                return []
        started: list[str] = []
        for config in configs:
            try:
                started += self._grow([config], origin, failed)
            except FleetError as exc:
                failed[config.robot] = exc.why
        return started

    def _grow(
        self, configs: Sequence[RuntimeConfig], origin: str, declined: dict[str, str] | None = None
    ) -> dict[str, Engine]:
        """Ports for `configs` on a link of their own, then their engines; on a failure nothing is left. A robot
        `admit` declines is not served (`declined` says why; without it, a `FleetError`)."""
        from td2adaptor.runtime.bus.bus import BusError
        from td2adaptor.runtime.bus.security import SecurityError
        from td2adaptor.runtime.ros.port import PortError, RosSetupError

        robots = ", ".join(c.robot for c in configs)
        if self.link.grow is None:
            raise FleetError(robots, "this ROS link cannot take robots at run time")
        started: dict[str, Engine] = {}
        link: RosLink | None = None
        try:
            self.check(configs)  # none another live process serves (OwnerConflict: a BusError)
            link = self.link.grow(configs)
            admitted: list[RuntimeConfig] = []
            for config in configs:
                why = self.admit(config) if self.admit is not None else None
                if why is not None:
                    if declined is None:
                        raise FleetError(config.robot, why)
                    declined[config.robot] = why
                    link.release(config.robot)
                    continue
                admitted.append(config)
            self._check_open()  # a `join`'s ROS side came up after the process began to stop: not served
            self._serve_all(admitted, link, origin, started)
            if not started:
                link.close()
        except Exception as exc:
            for robot in started:
                with self._lock:
                    engine = self._engines.pop(robot, None)
                    self._origin.pop(robot, None)
                    self._links.pop(robot, None)
                if engine is not None:
                    engine.stop()
            if link is not None:
                link.close()
            if isinstance(exc, FleetError):
                raise
            if not isinstance(exc, (RosSetupError, SecurityError, BusError, PortError, OSError)):
                log.exception("robot %s: could not start", robots)
                raise FleetError(robots, "could not start (the edge node's log says why)") from None
            raise FleetError(robots, str(exc)) from None
        for engine in started.values():
            robot = engine.config.robot
            log.info("robot %s: served from now on (%s)", robot, self.source(robot, origin))
            self._tell(self.on_added, engine)
        return started

    def _serve_all(
        self, configs: Sequence[RuntimeConfig], link: RosLink, origin: str, started: dict[str, Engine]
    ) -> None:
        """Serve `configs` (their ports on `link`), into `started`; raises what the first one that failed raised
        (the ones served stay in `started`, for the caller to stop). Together, on a few threads that end with the
        start: a robot's start is mostly waiting for its broker (connection, subscriptions, the retained TD and
        status acknowledged), and one after the other ten robots took ten times as long (issue 32: 1-4 s at load
        10-26, where the robots that joined must be served within 2 s)."""
        if len(configs) <= 1:
            for config in configs:
                started[config.robot] = self._serve(config, link.ports[config.robot], origin, link)
            return
        made: dict[str, Engine] = {}
        failure: BaseException | None = None
        with ThreadPoolExecutor(min(len(configs), STARTS_AT_ONCE), thread_name_prefix="td2adaptor-start") as pool:
            jobs = {c.robot: pool.submit(self._engine, c, link.ports[c.robot]) for c in configs}
            for robot, job in jobs.items():
                try:
                    made[robot] = job.result()
                except BaseException as exc:  # noqa: BLE001 - the first is raised once every start ended
                    failure = failure or exc
        for config in configs:  # in the order asked, on this thread
            engine = made.get(config.robot)
            if engine is None:
                continue
            try:
                started[config.robot] = self._keep(config, engine, origin, link)
            except FleetError as exc:  # the fleet stopped meanwhile (a `join`)
                failure = failure or exc
        if failure is not None:
            raise failure

    def _engine(self, config: RuntimeConfig, port: RobotPort) -> Engine:
        return serve(self.model, port, config, broker=self.broker, distro=self.distro, prepare=self.prepare)

    def _serve(self, config: RuntimeConfig, port: RobotPort, origin: str, link: RosLink | None = None) -> Engine:
        return self._keep(config, self._engine(config, port), origin, link)

    def _keep(self, config: RuntimeConfig, engine: Engine, origin: str, link: RosLink | None = None) -> Engine:
        """Register a robot's engine that serves already (under the lock: a `join` registers from its own
        thread); stopped instead when the fleet stopped meanwhile (a `join` outlived the process's stop)."""
        with self._lock:
            closed = self._closed
            if not closed:
                self._engines[config.robot] = engine
                self._origin[config.robot] = origin
                if link is not None:
                    self._links[config.robot] = link
        if closed:
            engine.stop()
            raise FleetError(config.robot, "the edge node is stopping")
        if self.on_halt is not None:
            engine.on_halt.append(partial(self.on_halt, config.robot))
            if engine.failure is not None:  # halted before the hook was in place
                self.on_halt(config.robot, engine.failure)
        return engine

    def _release(self, robot: str) -> None:
        """Close the robot's port, and its grown link once no robot of it is left."""
        link = self._links.pop(robot, None)
        if link is None:
            self.link.release(robot)
            return
        link.release(robot)
        if not link.ports:  # the last robot that joined with it
            link.close()

    @staticmethod
    def _tell(hooks: Sequence[Callable[..., None]], arg: object) -> None:
        for hook in list(hooks):
            try:
                hook(arg)
            except Exception:  # a hook must not keep the fleet from changing
                log.exception("a fleet hook failed")
