"""The RB-1 example as a model, the simulated robot behind a `SimPort`, and an application on a local bus."""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import td2adaptor
from examples.robotnik_rb1.sim.core import RobotSim
from td2adaptor.model import Model
from td2adaptor.model.events import TD_LEVEL, EventCatalog, Kind, build_catalog
from td2adaptor.runtime.events import EventValidator
from td2adaptor.runtime.localbus import LocalBroker, LocalBus
from tests.conftest import EXAMPLE

Event = tuple[str, dict[str, Any]]
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.5, "y": 3.0, "theta": 0.0}}]}}


def compile_td(path: Path) -> Model:
    result = td2adaptor.compile(path, interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return result.model


@cache
def rb1_model() -> Model:
    return compile_td(EXAMPLE / "td.json")


@cache
def rb1_catalog() -> EventCatalog:
    return build_catalog(rb1_model())


@cache
def rb1_validator() -> EventValidator:
    return EventValidator(rb1_catalog())


def td_with_security(tmp: Path, definitions: dict[str, Any]) -> Model:
    """The RB-1 TD with other securityDefinitions (all of them required)."""
    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    td["securityDefinitions"] = definitions
    td["security"] = list(definitions)
    path = tmp / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    return compile_td(path)


def check_outbound(events: list[Event]) -> None:
    """Every event the adaptor emitted conforms to its schema."""
    catalog, validator = rb1_catalog(), rb1_validator()
    for topic, event in events:
        if catalog.route(topic) is not None:
            continue  # sent by the test
        if topic.endswith("/" + TD_LEVEL):  # the robot's TD (or the empty message clearing it): no event
            assert event.get("@type") == "Thing" or event in ({"raw": ""}, {"raw": b""}), (topic, sorted(event))
            continue
        kind = Kind(event["type"])
        spec = catalog.find(kind, event.get("affordance") if kind not in (Kind.ERROR, Kind.STATUS) else None)
        assert spec.topic(event["robot"]) == topic
        assert validator.errors(spec, event) == [], (topic, event)


def sim(duration: float = 0.3, **kw: Any) -> RobotSim:
    return RobotSim(duration=duration, queue_time=kw.pop("queue_time", 0.05), **kw)


class LocalApp:
    """An application on a local bus: records events under `pattern`, sends events."""

    def __init__(self, broker: LocalBroker, pattern: str = "td2adaptor/#") -> None:
        self.events: list[Event] = []
        self.cond = threading.Condition()
        self.bus = LocalBus(broker, "app")
        self.bus.subscribe(pattern, self._on)
        self.bus.connect()

    def _on(self, msg: Any) -> None:
        try:
            data = json.loads(msg.payload)
        except ValueError:
            data = {"raw": msg.payload}
        with self.cond:
            self.events.append((msg.topic, data if isinstance(data, dict) else {"raw": data}))
            self.cond.notify_all()

    def send(self, topic: str, event: Any) -> None:
        self.bus.publish(topic, event if isinstance(event, bytes) else json.dumps(event).encode())

    def wait(self, predicate: Callable[[list[Event]], bool], timeout: float = 10.0) -> list[Event]:
        with self.cond:
            ok = self.cond.wait_for(lambda: predicate(self.events), timeout)
            assert ok, f"timed out; received {[(t, e.get('payload')) for t, e in self.events][-10:]}"
            return list(self.events)

    def of(self, kind: str, correlation: str | None = None) -> list[dict[str, Any]]:
        with self.cond:
            return [
                e
                for _, e in self.events
                if e.get("type") == kind and (correlation is None or e.get("correlation") == correlation)
            ]


def terminal(kind: str, correlation: str) -> Callable[[list[Event]], bool]:
    return lambda events: any(
        e.get("type") == kind and e.get("correlation") == correlation and e["payload"].get("terminal")
        for _, e in events
    )
