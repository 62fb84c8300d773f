"""The RB-1 example as a model, the simulated robot behind a `SimPort`, and an application on a local bus."""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

import td2adaptor
from examples.robotnik_rb1.sim.core import RobotSim
from td2adaptor.model import Model
from td2adaptor.model.events import TD_LEVEL, EventCatalog, EventSpec, Kind, build_catalog
from td2adaptor.model.wot import WOT_LEVEL, wot_data, wot_specs, wot_topic
from td2adaptor.runtime.bus.localbus import LocalBroker, LocalBus
from td2adaptor.runtime.events import EventValidator
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
def rb1_catalog(distro: str = "ros2") -> EventCatalog:
    return build_catalog(rb1_model(), distro)


@cache
def rb1_validator(distro: str = "ros2") -> EventValidator:
    return EventValidator(rb1_catalog(distro))


@cache
def wot_validators(robot: str, distro: str = "ros2") -> dict[str, tuple[EventSpec, Draft202012Validator]]:
    """WoT topic of `robot` -> (its event, a validator of the data there: unknown keys forbidden)."""
    out = {}
    for spec in wot_specs(rb1_catalog(distro)):
        topic = wot_topic(spec, robot)
        if topic is not None:
            out[topic] = (spec, Draft202012Validator(wot_data(spec)))
    return out


def td_with_security(tmp: Path, definitions: dict[str, Any]) -> Model:
    """The RB-1 TD with other securityDefinitions (all of them required)."""
    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    td["securityDefinitions"] = definitions
    td["security"] = list(definitions)
    path = tmp / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    return compile_td(path)


def check_outbound(events: list[Event], distro: str = "ros2") -> int:
    """Every event the adaptor emitted, and every WoT message, conforms to its (strict) schema for the robot's
    ROS version; the number checked."""
    catalog, validator = rb1_catalog(distro), rb1_validator(distro)
    checked = 0
    for topic, event in events:
        if catalog.route(topic) is not None:
            continue  # sent by the test
        levels = topic.split("/")
        if len(levels) > 2 and levels[2] == WOT_LEVEL:
            spec, wot = wot_validators(levels[1], distro)[topic]
            if not spec.kind.inbound:  # what the adaptor sent to WoT consumers (not what the test sent)
                value = event.get("raw") if set(event) == {"raw"} else event
                assert list(wot.iter_errors(value)) == [], (topic, event)
                checked += 1
            continue
        if topic.endswith("/" + TD_LEVEL):  # the robot's TD (or the empty message clearing it): no event
            assert event.get("@type") == "Thing" or event in ({"raw": ""}, {"raw": b""}), (topic, sorted(event))
            continue
        kind = Kind(event["type"])
        spec = catalog.find(kind, event.get("affordance") if kind not in (Kind.ERROR, Kind.STATUS) else None)
        assert spec.topic(event["robot"]) == topic
        assert validator.errors(spec, event) == [], (topic, event)
        checked += 1
    return checked


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
