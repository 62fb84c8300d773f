"""The robot's retained status, kept true while the edge node serves it.

`<root>/<robot>/status` says, retained (the envelope's status event, model/events.py):

* `state`: `online` while this node serves the robot, `offline` after it stopped, or died (the MQTT will);
* `robot`: whether the robot's ROS side is there (`present`, `partial`, `absent`; presence.py), with the
  actions whose server is `missing`;
* `owner`: the process serving it (owner.py), in the will too (the last one that served it);
* `missions`: missions in flight, and `lastError`: the last error event (code, message, time).

A `StatusKeeper` looks at the robot every `presence_period` on the process's engine loop (a timer, and the look
itself on the call pool: no thread of its own) and publishes the status when something in it changed, at most
once per period. It keeps the bus's birth message (published again at every reconnection) the current status.

The robots a process serves are looked at together (`_Looks`, one per loop and period): one timer, one pool
task that looks at each robot in turn, and one posted answer per period, whatever the number of robots. Each
robot's own timer, pool task and answer woke three threads per robot and second (300 wake-ups a second for
100 robots at idle, each for microseconds of work), and their looks, spread over the second, read the ROS 2
graph four times a second instead of once. A look that may block (ROS 1: the master over XML-RPC, up to 2 s)
is no part of the batch: it keeps its own pool task, so that a master that does not answer delays no other
robot's look.
"""

from __future__ import annotations

import functools
import logging
import threading
from collections import deque
from collections.abc import Callable, Mapping
from datetime import datetime, timezone
from typing import Any

from td2adaptor.runtime.bus.bus import Bus, BusError, Message
from td2adaptor.runtime.engine.engine import Engine, status_event
from td2adaptor.runtime.engine.missions import Mission
from td2adaptor.runtime.loop import Shared, Timer, acquire, release
from td2adaptor.runtime.node.owner import this_process
from td2adaptor.runtime.node.presence import DISCOVERY_SETTLE, Presence, Probe, quick

log = logging.getLogger("td2adaptor.runtime")

_keepers: dict[str, StatusKeeper] = {}  # every robot this process serves, by id (metrics.py reads them)
_keepers_lock = threading.Lock()


def keepers() -> list[StatusKeeper]:
    """The status keepers of the robots this process serves now."""
    with _keepers_lock:
        return list(_keepers.values())


def keeper_of(engine: Engine) -> StatusKeeper | None:
    """The status keeper of `engine`'s robot, while it keeps one."""
    with _keepers_lock:
        keeper = _keepers.get(engine.config.robot)
    return keeper if keeper is not None and keeper.engine is engine else None


def owner_fields() -> dict[str, Any]:
    """The status members that name this process (the birth, the will and every status in between)."""
    return {"owner": this_process().to_json()}


#: upper bounds (seconds) of the mission duration histogram the metrics show (metrics.py)
DURATION_BUCKETS = (0.01, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0, float("inf"))


#: the last statuses a keeper published, which its own retained status may still be after a reconnection
OURS_KEPT = 16


class Durations:
    """How long the robot's missions took, by how they ended: counts per bucket (not cumulative), sum, count."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.by_state: dict[str, tuple[list[int], float]] = {}

    def add(self, state: str, seconds: float) -> None:
        with self._lock:
            counts, total = self.by_state.get(state) or ([0] * len(DURATION_BUCKETS), 0.0)
            counts[next(i for i, bound in enumerate(DURATION_BUCKETS) if seconds <= bound)] += 1
            self.by_state[state] = (counts, total + seconds)

    def snapshot(self) -> dict[str, tuple[list[int], float]]:
        with self._lock:
            return {state: (list(counts), total) for state, (counts, total) in self.by_state.items()}


class StatusKeeper:
    """Keeps one robot's retained status true (see the module docstring); `stop()` before the engine stops."""

    def __init__(self, engine: Engine, raw: Bus, probe: Probe | None) -> None:
        self.engine = engine
        self.raw = raw  # the bus under the WoT adapter: its `birth` is kept current
        self.probe = probe
        config = engine.config
        self.period = config.presence_period
        self.presence = Presence(config.robot, grace=config.call_timeout, settle=DISCOVERY_SETTLE)
        self._shared: Shared | None = None
        self._looks: _Looks | None = None  # the process's periodic looks this robot is part of
        self._looking = False  # a look of this robot is under way on the pool (the loop's)
        self._stopped = False
        birth = getattr(raw, "birth", None)  # none from `serve` (app.py): the first `_publish` is the first status
        #: the payload published last (the birth's, when the bus publishes one on connecting)
        self._last: dict[str, Any] | None = {**owner_fields(), "missions": 0} if birth is not None else None
        self.durations = Durations()
        self._on_presence: list[Callable[[str | None], None]] = []  # told the robot's ROS side when it changes
        self._told: str | None = None  # the word the hooks and the log were told last (it also changes with time)
        self._offline: Message | None = None  # the `offline` made at the start (stop() stamps it anew)
        engine.outbox.on_end.append(self._ended)
        self._ours: deque[bytes] = deque([birth.payload] if birth is not None else [], maxlen=OURS_KEPT)

    def start(self) -> None:
        self._shared = acquire()
        if hasattr(self.raw, "owned"):  # an MQTT bus: checked on every reconnection
            self.raw.owned = self.owned
        if self.probe is not None and self.engine.absent is None and self.period > 0:
            self.engine.absent = self.presence.absent
        engine = self.engine
        engine.offline = self._offline = status_event(engine.config, engine.model, "offline", **owner_fields())
        with _keepers_lock:
            _keepers[engine.config.robot] = self
        if self.period > 0:
            self._looks = _Looks.join(self._shared, self.period, self)
        else:
            self._shared.loop.post(self._tick)

    def follow_presence(self, hook: Callable[[str | None], None]) -> None:
        """Tell `hook` the robot's ROS side now (if a look found it yet) and at every change: a hook added after
        the first look must not wait for the next change to learn it."""
        self._on_presence.append(hook)
        hook(self.presence.word())

    def _ended(self, mission: Mission, state: str) -> None:
        self.durations.add(state, max(0.0, self.engine.clock() - mission.started))

    def stop(self) -> None:
        """No more looks and no more status (the engine publishes `offline` next, stamped now unless a share
        replaced it: an `offline` stamped at the start would look older than the statuses before it)."""
        self._stopped = True
        engine = self.engine
        if self._offline is not None and engine.offline is self._offline:
            engine.offline = status_event(engine.config, engine.model, "offline", **owner_fields())
        looks, self._looks = self._looks, None
        if looks is not None:
            looks.leave(self)
        with _keepers_lock:
            if _keepers.get(self.engine.config.robot) is self:
                del _keepers[self.engine.config.robot]
        shared, self._shared = self._shared, None
        if shared is not None:
            release(shared)

    # -- on the loop -----------------------------------------------------------------------------------------

    def _tick(self) -> None:
        """(the loop) Once, when the robot is not looked at periodically: publish its status."""
        if not self._stopped and self._shared is not None:
            self._publish()

    def _look(self) -> Mapping[str, bool] | None:
        """(the pool) Look at the robot's ROS side (None: the look failed and says nothing; the next one may)."""
        assert self.probe is not None
        try:
            return self.probe()
        except Exception:  # noqa: BLE001 - a failed look says nothing; the next one may
            log.exception("robot %s: looking at its ROS side failed", self.engine.config.robot)
            return None

    def _seen(self, ready: Mapping[str, bool] | None) -> None:
        self._looking = False
        if self._stopped:
            return
        if ready is not None:
            self.presence.update(ready)
            now = self.presence.word()
            if now != self._told:
                self._told = now
                for hook in self._on_presence:
                    try:
                        hook(now)
                    except Exception:  # noqa: BLE001 - a hook must not keep the status from being published
                        log.exception("robot %s: a presence hook failed", self.engine.config.robot)
                missing = ", ".join(self.presence.missing())
                log.info(
                    "robot %s: ROS side %s%s", self.engine.config.robot, now, f" (missing {missing})" * bool(missing)
                )
        self._publish()

    def published(self) -> dict[str, Any]:
        """The payload of the last status published (a copy; {} before the first): a hand-over's status says the
        robot's side and last error as it stood (share.py)."""
        return dict(self._last or {})

    def payload(self) -> dict[str, Any]:
        """The status payload as it stands (without `state` and `thing`, which `status_event` adds)."""
        out: dict[str, Any] = {}
        word = self.presence.word()
        if word is not None:
            out["robot"] = word
            missing = self.presence.missing()
            if missing:
                out["missing"] = missing[:32]
        out.update(owner_fields())
        out["missions"] = len(self.engine.missions.running())
        last = self.engine.outbox.last_error
        if last is not None:
            code, message, when = last
            stamp = datetime.fromtimestamp(when, timezone.utc).isoformat(timespec="milliseconds")
            out["lastError"] = {"code": code, "message": message[:1024], "time": stamp.replace("+00:00", "Z")}
        return out

    def _publish(self) -> None:
        payload = self.payload()
        if payload == self._last:
            return
        engine = self.engine
        message = status_event(engine.config, engine.model, "online", **payload)
        try:
            engine.bus.publish(message.topic, message.payload, retain=True)
        except BusError as exc:  # published again with the next change, and as the birth on reconnecting
            log.warning("robot %s: could not publish its status: %s", engine.config.robot, exc)
        self.raw.birth = message  # type: ignore[attr-defined]
        self._ours.append(message.payload)
        self._last = payload

    def owned(self) -> str | None:
        """(the bus's network thread, on reconnecting) Whether another node took the robot's session over while
        this one was away (owner.py): its retained status is then none of ours."""
        from td2adaptor.runtime.node.owner import probe_bus, read_statuses, taken_by

        raw: Any = self.raw
        topic = f"{self.engine.config.topic_root}/{self.engine.config.robot}/status"
        seen = read_statuses(probe_bus(raw.address, raw.security, raw.mqtt_version), [topic])
        return taken_by(self.engine.config.robot, seen.get(topic), list(self._ours))


class _Looks:
    """Every `presence_period` (`period`), the looks at the robots of one loop that share that period, as one
    timer of the loop, one pool task for every look that does not block (`presence.quick`) and one answer posted
    back (see the module docstring); a look that may block has a pool task of its own, as before."""

    _all: dict[tuple[int, float], _Looks] = {}  # by the loop's id and the period: while a robot is part of them
    _all_lock = threading.Lock()

    def __init__(self, shared: Shared, period: float) -> None:
        self.shared = shared
        self.period = period
        self.keepers: dict[StatusKeeper, None] = {}  # in the order they joined (guarded by _all_lock)
        self.timer: Timer | None = None
        self.started = False

    @classmethod
    def join(cls, shared: Shared, period: float, keeper: StatusKeeper) -> _Looks:
        """`keeper`'s robot is looked at with the others of `shared`'s loop every `period` from now on (its
        first look at the next turn of the loop, as a robot's first look was)."""
        with cls._all_lock:
            looks = cls._all.get((id(shared.loop), period))
            if looks is None or looks.shared is not shared:
                looks = cls._all[id(shared.loop), period] = _Looks(shared, period)
            looks.keepers[keeper] = None
            start, looks.started = not looks.started, True
        if start:
            shared.loop.post(looks._tick)
        else:
            shared.loop.post(looks._batch_of, [keeper])  # looked at alone once, then with the others
        return looks

    def leave(self, keeper: StatusKeeper) -> None:
        """`keeper` stopped: not looked at any more; the last one to leave ends the timer."""
        with _Looks._all_lock:
            self.keepers.pop(keeper, None)
            if self.keepers:
                return
            if _Looks._all.get((id(self.shared.loop), self.period)) is self:
                del _Looks._all[id(self.shared.loop), self.period]
            timer, self.timer = self.timer, None
        if timer is not None:
            timer.cancel()

    def _tick(self) -> None:
        """(the loop) Look at every robot (the period's timer)."""
        with _Looks._all_lock:
            keepers = list(self.keepers)
            if not keepers:
                return
        self._batch_of(keepers)
        with _Looks._all_lock:
            if self.keepers:
                self.timer = self.shared.loop.call_later(self.period, self._tick)

    def _batch_of(self, keepers: list[StatusKeeper]) -> None:
        """(the loop) Look at `keepers`' robots: those whose look does not block in one pool task, each other on
        its own, the robots without a look (or with one under way) publish their status as it stands."""
        batch: list[StatusKeeper] = []
        for keeper in keepers:
            if keeper._stopped:
                continue
            if keeper.probe is None or keeper._looking:
                keeper._publish()
                continue
            keeper._looking = True
            if quick(keeper.probe):
                batch.append(keeper)
            else:  # a look that may block (see `presence.quick`): a task of its own
                self.shared.pool.submit(functools.partial(self._look, [keeper]))
        if batch:
            self.shared.pool.submit(functools.partial(self._look, batch))

    def _look(self, keepers: list[StatusKeeper]) -> None:
        """(the pool) Look at each robot in turn; the loop takes the answers at once."""
        self.shared.loop.post(self._seen, [(keeper, keeper._look()) for keeper in keepers])

    @staticmethod
    def _seen(answers: list[tuple[StatusKeeper, Mapping[str, bool] | None]]) -> None:
        for keeper, ready in answers:
            keeper._seen(ready)


def watch(engine: Engine, raw: Bus, port: Any) -> StatusKeeper:
    """Keep `engine`'s robot's status true (its presence watched through `port`); stopped with the engine."""
    from td2adaptor.model.events import Kind
    from td2adaptor.runtime.node.presence import probe_of

    actions = [s.affordance for s in engine.catalog.specs if s.kind is Kind.INVOKE and s.affordance]
    keeper = StatusKeeper(engine, raw, probe_of(port, actions, engine.model, engine.config))
    engine.on_stop.insert(0, keeper.stop)
    keeper.start()
    return keeper
