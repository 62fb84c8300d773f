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
"""

from __future__ import annotations

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
from td2adaptor.runtime.node.presence import DISCOVERY_SETTLE, Presence, Probe

log = logging.getLogger("td2adaptor.runtime")

_keepers: dict[str, StatusKeeper] = {}  # every robot this process serves, by id (metrics.py reads them)
_keepers_lock = threading.Lock()


def keepers() -> list[StatusKeeper]:
    """The status keepers of the robots this process serves now."""
    with _keepers_lock:
        return list(_keepers.values())


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
        self._timer: Timer | None = None
        self._looking = False  # a look is under way on the pool
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
        if self._timer is not None:
            self._timer.cancel()
        with _keepers_lock:
            if _keepers.get(self.engine.config.robot) is self:
                del _keepers[self.engine.config.robot]
        shared, self._shared = self._shared, None
        if shared is not None:
            release(shared)

    # -- on the loop -----------------------------------------------------------------------------------------

    def _tick(self) -> None:
        shared = self._shared
        if self._stopped or shared is None:
            return
        if self.probe is not None and self.period > 0 and not self._looking:
            self._looking = True
            shared.pool.submit(self._look)
        else:
            self._publish()
        if self.period > 0:
            self._timer = shared.loop.call_later(self.period, self._tick)

    def _look(self) -> None:
        """(the pool) Look at the robot's ROS side; the loop takes the answer."""
        assert self.probe is not None
        try:
            ready: Mapping[str, bool] | None = self.probe()
        except Exception:  # noqa: BLE001 - a failed look says nothing; the next one may
            log.exception("robot %s: looking at its ROS side failed", self.engine.config.robot)
            ready = None
        shared = self._shared
        if shared is not None:
            shared.loop.post(self._seen, ready)

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


def watch(engine: Engine, raw: Bus, port: Any) -> StatusKeeper:
    """Keep `engine`'s robot's status true (its presence watched through `port`); stopped with the engine."""
    from td2adaptor.model.events import Kind
    from td2adaptor.runtime.node.presence import probe_of

    actions = [s.affordance for s in engine.catalog.specs if s.kind is Kind.INVOKE and s.affordance]
    keeper = StatusKeeper(engine, raw, probe_of(port, actions, engine.model, engine.config))
    engine.on_stop.insert(0, keeper.stop)
    keeper.start()
    return keeper
