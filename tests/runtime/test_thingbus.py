"""The WoT adapter at the bus edge (runtime/bus/thingbus.py), on the in-process bus with the simulated RB-1: a WoT
consumer's messages (the affordance's own data) become the engine's envelope events and back, for every kind;
what it cannot wrap is answered as a native client's would be; the envelope topics stay as they were."""

from __future__ import annotations

import json
from typing import Any

import pytest
from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

from td2adaptor.model.events import Kind
from td2adaptor.model.wot import CORRELATION, WOT_LEVEL, action_input, wot_specs, wot_topic
from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.localbus import LocalBus
from td2adaptor.runtime.bus.thingbus import WOT_SOURCE, ThingBus
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_catalog, rb1_model, rb1_validator, sim

ROBOT = "thing_rb1"
T = f"td2adaptor/{ROBOT}/{WOT_LEVEL}"


@pytest.fixture
def rig() -> Any:
    model = rb1_model()
    broker = LocalBroker()
    app = LocalApp(broker)
    robot = sim(0.3)
    config = RuntimeConfig(robot=ROBOT, poll_period=0.02, property_period=0.05, state_dir="")
    engine = serve(model, SimPort(model, robot), config, broker=broker)
    yield app, robot
    engine.stop()
    assert check_outbound(app.events) > 0  # every message the edge node sent, envelope or WoT, strictly valid


def _on(app: LocalApp, topic: str) -> list[dict[str, Any]]:
    return [e for t, e in app.events if t == topic]


def test_a_goal_sent_as_its_fields_runs_and_is_answered_with_its_correlation(rig: Any) -> None:
    app, robot = rig
    app.send(f"{T}/GoToComponent/gotoRun", {**GOAL, CORRELATION: "job-1"})
    app.wait(lambda ev: any(e.get(CORRELATION) == "job-1" and e.get("terminal") for _, e in ev))
    wot = _on(app, f"{T}/GoToComponent/gotoRun/feedback")
    assert [e["state"] for e in wot][-1] == "finished" and {e["mission"] for e in wot} == {1}
    assert all("payload" not in e and "type" not in e for e in wot)  # the outcome itself, no envelope
    # the engine saw an envelope event, answered on the envelope topic too
    native = [e for e in app.of("feedback", "job-1")]
    assert native and all(e["robot"] == ROBOT for e in native)
    assert [e["payload"]["seq"] for e in native] == [e["seq"] for e in wot]
    assert robot.x == 1.5 and robot.y == 3.0  # it moved where the goal said


def test_query_and_cancel_take_the_mission_and_answer_on_the_state_event(rig: Any) -> None:
    app, _ = rig
    app.send(f"{T}/GoToComponent/gotoRun", {**GOAL, CORRELATION: "long"})
    app.wait(lambda ev: any(t == f"{T}/GoToComponent/gotoRun/feedback" for t, _ in ev))
    mission = _on(app, f"{T}/GoToComponent/gotoRun/feedback")[0]["mission"]
    app.send(f"{T}/GoToComponent/gotoQuery", {"mission": mission, CORRELATION: "q"})
    app.send(f"{T}/GoToComponent/gotoCancel", {CORRELATION: "c"})  # no mission: the current one
    app.wait(lambda ev: {e.get(CORRELATION) for t, e in ev if t.endswith("/gotoRun/state")} >= {"q", "c"})
    states = {e[CORRELATION]: e for e in _on(app, f"{T}/GoToComponent/gotoRun/state")}
    assert states["q"]["mission"] == mission and states["c"]["state"] == "cancelled"
    app.wait(lambda ev: any(e.get(CORRELATION) == "long" and e.get("terminal") for _, e in ev))


def test_properties_are_the_messages_themselves_and_writes_take_the_value(rig: Any) -> None:
    app, robot = rig
    app.wait(lambda ev: any(t == f"{T}/PoseMarkerComponent/poseMarker" for t, _ in ev))
    (value, *_) = _on(app, f"{T}/PoseMarkerComponent/poseMarker")
    assert set(value) == {"header", "markers"}
    app.send(f"{T}/DoorComponent/door", {"data": 0.25})
    app.wait(lambda ev: robot.door_command == 0.25)


@pytest.mark.parametrize(
    ("topic", "raw", "code", "words"),
    [
        ("PickComponent/pickRun", {"nope": 1, CORRELATION: "bad"}, "invalid-event", "'nope' was unexpected"),
        ("PickComponent/pickRun", {"markerID": 2, CORRELATION: "bad"}, "invalid-event", "'markerID' was unexpected"),
        ("DoorComponent/door", {"linear": {"x": "fast"}}, "invalid-event", "'linear' was unexpected"),
        ("DoorComponent/door", {"data": "fast"}, "invalid-event", "is not of type 'number'"),
        ("GoToComponent/gotoQuery", {"mission": "seven", CORRELATION: "bad"}, "invalid-event", "integer"),
        ("GoToComponent/gotoQuery", {"which": 1, CORRELATION: "bad"}, "invalid-event", "'which' was unexpected"),
        ("GoToComponent/gotoRun", {**GOAL, CORRELATION: 5}, "invalid-event", "correlation"),
        ("GoToComponent/gotoRun", b"{not json", "invalid-json", "not a JSON document"),
    ],
)
def test_bad_input_is_refused_early_in_words(rig: Any, topic: str, raw: Any, code: str, words: str) -> None:
    app, robot = rig
    app.send(f"{T}/{topic}", raw)
    app.wait(lambda ev: any(t == f"{T}/error" for t, _ in ev))
    (error,) = _on(app, f"{T}/error")
    assert error["code"] == code and words in error["message"], error
    assert error["affordance"] == topic.rsplit("/", 1)[1] and error["topic"] == f"{T}/{topic}"
    assert "Port" not in error["message"] and "Error:" not in error["message"]
    if isinstance(raw, dict) and raw.get(CORRELATION) == "bad":
        assert error[CORRELATION] == "bad"
    assert robot.next_id == 0 and robot.door_command is None  # nothing reached the robot


def test_the_wrapped_event_is_one_the_engine_validates() -> None:
    """The adapter's envelope is a valid event for every inbound kind (the engine then decides)."""
    catalog = rb1_catalog()
    bus = ThingBus(LocalBus(LocalBroker(), "t"), catalog, ROBOT)
    samples: dict[Kind, Any] = {
        Kind.INVOKE: {**GOAL, CORRELATION: "c"},
        Kind.QUERY: {"mission": 3, CORRELATION: "c"},
        Kind.CANCEL: {},
        Kind.WRITE: {"data": 1.0},
    }
    checked = 0
    for spec in catalog.inbound():
        if spec.affordance not in ("gotoRun", "gotoQuery", "gotoCancel", "door"):
            continue
        event = json.loads(bus.wrap(spec, json.dumps(samples[spec.kind]).encode()))
        assert rb1_validator().errors(spec, event) == [], (spec.key, event)
        assert event["source"] == WOT_SOURCE and event["robot"] == ROBOT
        checked += 1
    assert checked == 4
    # an empty invocation (node-wot sends nothing without an input) is an empty goal
    spec = catalog.find(Kind.QUERY, "gotoQuery")
    assert "payload" not in json.loads(bus.wrap(spec, b""))


def test_events_without_a_wot_form_pass_through_unchanged() -> None:
    catalog = rb1_catalog()
    broker = LocalBroker()
    seen: list[Message] = []
    watcher = LocalBus(broker, "w")
    watcher.subscribe("#", seen.append)
    watcher.connect()
    bus = ThingBus(LocalBus(broker, "t"), catalog, ROBOT)
    bus.connect()
    bus.publish(f"td2adaptor/{ROBOT}/status", b'{"type":"status"}', retain=True)
    bus.publish(f"td2adaptor/{ROBOT}/td", b"", retain=True)
    unknown = {"type": "error", "robot": ROBOT, "payload": {"code": "unknown-topic", "message": "m"}}
    bus.publish(f"td2adaptor/{ROBOT}/error", json.dumps(unknown).encode())  # no affordance: envelope only
    assert watcher.drain(5) and bus.flush(5)
    assert [m.topic for m in seen] == [
        f"td2adaptor/{ROBOT}/status",
        f"td2adaptor/{ROBOT}/td",
        f"td2adaptor/{ROBOT}/error",
    ]


def test_every_action_input_declares_the_correlation_and_keeps_the_goal() -> None:
    for spec in wot_specs(rb1_catalog()):
        if spec.kind is Kind.INVOKE:
            schema = action_input(spec)
            assert CORRELATION in schema["properties"] and schema["additionalProperties"] is False
            Draft202012Validator.check_schema(schema)
            assert Draft202012Validator(schema).is_valid({**GOAL, CORRELATION: "x"}) == (spec.affordance == "gotoRun")
        assert wot_topic(spec, ROBOT) is not None


class _CountingJson:
    """The `json` module as thingbus.py sees it, counting `loads`: how often the adapter parses an event."""

    def __init__(self) -> None:
        self.loads_calls = 0

    def loads(self, raw: Any) -> Any:
        self.loads_calls += 1
        return json.loads(raw)

    def dumps(self, *args: Any, **kw: Any) -> str:
        return json.dumps(*args, **kw)


@pytest.mark.parametrize("ledger", [False, True])
def test_each_event_is_encoded_once_and_its_wot_form_is_the_one_read_back_from_it(
    ledger: bool, tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The engine's events reach ThingBus as objects: the WoT form is made without parsing the envelope the
    engine just encoded, and is byte for byte what reading the envelope back gives (properties, feedback,
    state, errors, with and without the ledger)."""
    from td2adaptor.runtime.bus import thingbus

    counting = _CountingJson()
    monkeypatch.setattr(thingbus, "json", counting)
    model = rb1_model()
    broker = LocalBroker()
    seen: list[Message] = []
    watcher = LocalBus(broker, "w")
    watcher.subscribe("td2adaptor/#", seen.append)
    watcher.connect()
    app = LocalApp(broker)
    state = str(tmp_path) if ledger else ""
    config = RuntimeConfig(robot=ROBOT, poll_period=0.02, property_period=0.05, state_dir=state)
    engine = serve(model, SimPort(model, sim(0.3)), config, broker=broker)
    try:
        app.send(f"{T}/GoToComponent/gotoRun", {**GOAL, CORRELATION: "job"})
        app.wait(lambda ev: any(t == f"{T}/GoToComponent/gotoRun/feedback" for t, _ in ev))
        app.send(f"{T}/GoToComponent/gotoQuery", {"mission": 1, CORRELATION: "q"})
        app.send(f"{T}/PickComponent/pickRun", {"nope": 1, CORRELATION: "bad"})
        app.wait(lambda ev: any(e.get(CORRELATION) == "job" and e.get("terminal") for _, e in ev))
        app.wait(lambda ev: {e.get(CORRELATION) for t, e in ev} >= {"q", "bad"})
    finally:
        engine.stop()
    assert watcher.drain(5)
    published = counting.loads_calls
    reference = ThingBus(LocalBus(LocalBroker(), "r"), rb1_catalog(), ROBOT)  # reads each envelope back
    expected: list[tuple[str, str]] = []
    for msg in seen:
        spec = reference._outbound.get(msg.topic)
        if spec is None or spec.kind is Kind.STATUS or not msg.payload:
            continue
        out = reference.unwrap(spec, json.loads(msg.payload))
        if out is not None:
            expected.append((out[0], json.dumps(out[1], separators=(",", ":"), ensure_ascii=False)))
    wot = [(m.topic, m.payload.decode()) for m in seen if m.topic.startswith(f"{T}/") and m.payload]
    wot = [(t, p) for t, p in wot if not t.endswith(("/gotoRun", "/gotoQuery", "/pickRun"))]  # the app's own
    kinds = {t.rsplit("/", 1)[1] for t, _ in expected}
    assert {"feedback", "state", "error"} <= kinds and len(expected) > 5, kinds
    assert sorted(wot) == sorted(expected)
    assert published == 0, f"the adapter parsed {published} of the engine's events again"
