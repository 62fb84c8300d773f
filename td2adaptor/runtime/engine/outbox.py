"""Everything one robot's engine publishes, and the count of it: one object the engine hands to the goal runner
and the property streams instead of itself.

* error events (`error`), state events (`state`: the answer to a query or cancel), feedback events
  (`feedback`: numbered 1, 2, ... per mission; a mission in the ledger has every state change and its end
  written there before the event is published, ledger.py), the one terminal feedback of a mission (`finish`,
  which frees its component in the `MissionTable` first) and any other event (`publish`, `send`);
* `stats` counts what went out (`out.<kind>`) and whatever else the engine and the streams count (`count`).

A failure to publish is logged and costs that event; it never reaches the caller (a mission goes on).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

from td2adaptor.model.events import EventCatalog, EventSpec, Kind
from td2adaptor.runtime.bus.bus import Bus, BusError, when_flushed
from td2adaptor.runtime.bus.thingbus import ThingBus
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.ledger import SEQ_BLOCK, Ledger
from td2adaptor.runtime.engine.missions import Mission, MissionTable
from td2adaptor.runtime.events import encode, envelope, excerpt
from td2adaptor.runtime.ros.procedures import ProcedureStatus

log = logging.getLogger("td2adaptor.runtime")


class Outbox:
    """The events of one robot, published on its bus (see the module docstring)."""

    def __init__(
        self, bus: Bus, config: RuntimeConfig, catalog: EventCatalog, ledger: Ledger, missions: MissionTable
    ) -> None:
        self.bus = bus
        self.config = config
        self.catalog = catalog
        self.ledger = ledger
        self.missions = missions
        self.stats: dict[str, int] = {}
        self.last_error: tuple[str, str, float] | None = None  # code, message, time.time() (the robot's status)
        self.on_end: list[Callable[[Mission, str], None]] = []  # told each mission's end and its state (metrics)
        self._lock = threading.Lock()
        self._unsent: set[str] = set()  # missions whose terminal event the broker has not acknowledged yet
        self._gone = False  # the bus stopped serving for good (`abandon`)

    def count(self, key: str, n: int = 1) -> None:
        with self._lock:
            self.stats[key] = self.stats.get(key, 0) + n

    def publish(self, spec: EventSpec, event: Mapping[str, Any], *, retain: bool = False, qos: int = 1) -> None:
        try:
            data = encode(event)
        except (TypeError, ValueError) as exc:
            log.error("could not publish a %s event: %s", spec.kind.value, exc)
            return
        self.send(spec, data, retain=retain, qos=qos, event=event)

    def send(
        self,
        spec: EventSpec,
        data: bytes,
        *,
        retain: bool = False,
        qos: int = 1,
        event: Mapping[str, Any] | None = None,
    ) -> None:
        """Publish `data`; `event`, when given, is what `data` encodes: a WoT adapter makes its WoT form from
        it instead of parsing `data` again (thingbus.py)."""
        try:
            topic = spec.topic(self.config.robot, self.config.topic_root)
            if event is not None and isinstance(self.bus, ThingBus):
                self.bus.publish_event(topic, data, event, retain=retain, qos=qos)
            else:
                self.bus.publish(topic, data, retain=retain, qos=qos)
            self.count(f"out.{spec.kind.value}")
        except (BusError, TypeError, ValueError) as exc:
            log.error("could not publish a %s event: %s", spec.kind.value, exc)

    def event(self, kind: Kind, payload: Any, **kw: Any) -> dict[str, Any]:
        return envelope(kind, robot=self.config.robot, source=self.config.event_source, payload=payload, **kw)

    def error(
        self,
        code: str,
        message: str,
        *,
        topic: str,
        raw: bytes | None = None,
        affordance: str | None = None,
        correlation: str | None = None,
        mission: int | None = None,
        errors: tuple[tuple[str, str], ...] = (),
    ) -> None:
        log.warning("%s on %s: %s", code, topic, message)
        self.last_error = (code, message, time.time())
        payload: dict[str, Any] = {"code": code, "message": message, "topic": topic}
        if raw is not None:
            payload["event"] = excerpt(raw)
        if errors:
            payload["errors"] = [{"path": p, "message": m} for p, m in errors]
        event = self.event(Kind.ERROR, payload, affordance=affordance, correlation=correlation, mission=mission)
        self.publish(self.catalog.find(Kind.ERROR), event)

    def state(
        self,
        run: str,
        status: ProcedureStatus,
        correlation: str | None,
        mission: int | None,
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        payload = {**status.payload(), "terminal": status.terminal, **(extra or {})}
        event = self.event(Kind.STATE, payload, affordance=run, correlation=correlation, mission=mission)
        self.publish(self.catalog.find(Kind.STATE, run), event)

    def feedback(
        self,
        m: Mission,
        status: ProcedureStatus,
        *,
        terminal: bool,
        output: Any = None,
        extra: Mapping[str, Any] | None = None,
    ) -> None:
        changed = status.state != m.state
        m.seq += 1
        m.state = status.state
        payload: dict[str, Any] = {**status.payload(), "terminal": terminal, "seq": m.seq, **(extra or {})}
        if m.goal is not None:
            payload["goal"] = m.goal
        if output is not None:
            payload["output"] = output
        event = self.event(Kind.FEEDBACK, payload, affordance=m.action, correlation=m.correlation, mission=m.mission_id)
        spec = self.catalog.find(Kind.FEEDBACK, m.action)
        if m.key is None:
            self.publish(spec, event)
            if terminal:
                self._ended(m)
            return
        try:
            data = encode(event)
        except (TypeError, ValueError) as exc:
            log.error("could not publish a %s event: %s", spec.kind.value, exc)
            return
        self._record(m, data, terminal, changed)
        self.send(spec, data, event=event)
        if terminal:
            self._done_when_sent(m.key)
            self._ended(m)

    def _done_when_sent(self, key: str) -> None:
        """The mission's ledger row is done once the broker has its terminal event (QoS 1 acknowledged), not
        when the bus client has it: a node killed or frozen in between (the packet still in its queue or its
        socket) left a row `done` whose event never reached anyone, and nothing sent it again. Until then the
        row stays `ending`, and a next start (or the next owner of the robot) sends the same event again."""
        with self._lock:
            gone = self._gone
            if not gone:
                self._unsent.add(key)
        if gone:
            self.ledger.done(key)
            return
        when_flushed(self.bus, partial(self._sent, key))

    def _sent(self, key: str) -> None:
        with self._lock:
            if key not in self._unsent:  # abandoned meanwhile: done already
                return
            self._unsent.discard(key)
        self.ledger.done(key)

    def abandon(self) -> None:
        """The bus stopped serving the broker for good (another process took the robot's session over: the
        engine's halt): what it has not delivered never will be, and it is the next owner's to end those
        missions. Their rows are done now, and so is every end from now on: sent again at a later start (a
        robot handed back), such an end would be a second one."""
        with self._lock:
            self._gone = True
            keys, self._unsent = self._unsent, set()
        for key in keys:
            self.ledger.done(key)

    def _ended(self, m: Mission) -> None:
        for hook in self.on_end:
            try:
                hook(m, m.state or "")
            except Exception:  # noqa: BLE001 - a hook must not cost the mission its end
                log.exception("mission end hook failed")

    def _record(self, m: Mission, data: bytes, terminal: bool, changed: bool) -> None:
        """Put a feedback event in the ledger before it is published (see ledger.py): every state change and
        the end with the event itself; feedback that changes nothing (a goal's) only numbers reserved ahead."""
        assert m.key is not None
        if terminal or changed:
            m.reserved = m.seq
            latest = data.decode("utf-8")
            self.ledger.event(
                m.key,
                mission=m.mission_id,
                goal=m.goal,
                state=m.state or "",
                seq=m.seq,
                reserved=m.seq,
                latest=latest,
                terminal=terminal,
            )
        elif m.seq > m.reserved:
            m.reserved = m.seq + SEQ_BLOCK
            self.ledger.reserve(m.key, m.reserved)

    def finish(self, m: Mission, status: ProcedureStatus, output: Any = None) -> None:
        """The one terminal feedback; the component is free again before it is published."""
        late = self.missions.end(m)
        if late is None:
            return
        self.feedback(m, status, terminal=True, output=output)
        extra = {"goal": m.goal} if m.goal is not None else None
        for correlation in late:  # cancels that came as the mission ended: its end is their answer
            self.state(m.action, status, correlation, m.mission_id, extra)
