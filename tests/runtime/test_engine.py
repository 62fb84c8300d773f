"""The engine on the in-process bus with the simulated RB-1: missions, cancel, query, errors, faults."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from typing import Any

import pytest

from td2adaptor.runtime import (
    Engine,
    LocalBroker,
    LocalBus,
    PortCallFailed,
    RuntimeConfig,
    StartResult,
    serve,
    serve_fleet,
)
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_model, sim, terminal

ROBOT = "rb1_base_a"
GOTO = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"
CANCEL = f"td2adaptor/{ROBOT}/GoToComponent/gotoCancel"
QUERY = f"td2adaptor/{ROBOT}/GoToComponent/gotoQuery"
PICK = f"td2adaptor/{ROBOT}/PickComponent/pickRun"


def config(**kw: Any) -> RuntimeConfig:
    base: dict[str, Any] = {"robot": ROBOT, "poll_period": 0.02, "property_period": 0, "call_timeout": 1.0}
    return RuntimeConfig(**{**base, **kw})


class Rig:
    def __init__(self, duration: float = 0.3, **cfg: Any) -> None:
        self.broker = LocalBroker()
        self.model = rb1_model()
        self.sim = sim(duration)
        self.port = SimPort(self.model, self.sim)
        self.app = LocalApp(self.broker)
        self.engine = serve(self.model, self.port, config(**cfg), broker=self.broker)

    def feedback(self, correlation: str) -> list[dict[str, Any]]:
        return [e for e in self.app.of("feedback", correlation)]

    def close(self) -> None:
        self.engine.stop()
        check_outbound(self.app.events)


@pytest.fixture
def rig() -> Iterator[Rig]:
    r = Rig()
    yield r
    r.close()


def test_goto_reports_every_state_then_one_terminal(rig: Rig) -> None:
    rig.app.send(GOTO, {"id": "e1", "correlation": "m1", "source": "test", "payload": GOAL})
    rig.app.wait(terminal("feedback", "m1"))
    fb = rig.feedback("m1")
    assert [e["payload"]["state"] for e in fb] == ["queued", "running", "finished"]
    assert [e["payload"]["seq"] for e in fb] == [1, 2, 3]
    assert [e["payload"]["terminal"] for e in fb] == [False, False, True]
    assert {e["mission"] for e in fb} == {1}
    assert fb[-1]["payload"]["message"] == "Perfect" and fb[-1]["payload"]["result"] == "ok"
    assert (rig.sim.x, rig.sim.y) == (1.5, 3.0)
    # queried by the id the robot returned, never -1
    time.sleep(0.05)
    assert rig.engine.idle()


def test_second_action_on_a_busy_component_is_refused(rig: Rig) -> None:
    rig.app.send(GOTO, {"correlation": "first", "payload": GOAL})
    rig.app.send(GOTO, {"correlation": "second", "payload": GOAL})
    rig.app.wait(terminal("feedback", "first"))
    rig.app.wait(terminal("feedback", "second"))
    second = rig.feedback("second")
    assert len(second) == 1 and second[0]["payload"]["state"] == "failed"
    assert second[0]["payload"]["reason"] == "busy"
    errors = rig.app.of("error", "second")
    assert errors and errors[0]["payload"]["code"] == "busy"
    assert "GoToComponent is busy with gotoRun mission 1" in errors[0]["payload"]["message"]
    assert rig.feedback("first")[-1]["payload"]["state"] == "finished"
    # another component is independent; the same component is free again after the terminal event
    rig.app.send(PICK, {"correlation": "pick", "payload": {"procedure": {"pick_frame_id": "cart"}}})
    rig.app.send(GOTO, {"correlation": "third", "payload": GOAL})
    rig.app.wait(terminal("feedback", "pick"))
    rig.app.wait(terminal("feedback", "third"))
    assert rig.feedback("third")[-1]["payload"]["state"] == "finished"


def test_cancel_reports_cancelled_and_answers_the_cancel() -> None:
    r = Rig(duration=30.0)
    try:
        r.app.send(GOTO, {"correlation": "long", "payload": GOAL})
        r.app.wait(lambda ev: any(e.get("payload", {}).get("state") == "running" for _, e in ev))
        r.app.send(CANCEL, {"correlation": "stop-it"})
        r.app.wait(terminal("feedback", "long"))
        fb = r.feedback("long")
        assert fb[-1]["payload"]["state"] == "cancelled" and fb[-1]["payload"]["terminal"]
        answer = r.app.wait(terminal("state", "stop-it"))
        state = [e for _, e in answer if e.get("type") == "state"][0]
        assert state["payload"]["state"] == "cancelled" and state["mission"] == fb[0]["mission"]
        assert ("GoToComponent", "gotoCancel") in r.port.calls
        # a cancel with nothing running still answers (the robot says what it knows about the last mission)
        r.app.send(CANCEL, {"correlation": "again"})
        again = r.app.wait(terminal("state", "again"))
        assert [e for _, e in again if e.get("correlation") == "again"][-1]["payload"]["state"] == "cancelled"
    finally:
        r.close()


def test_query_answers_with_the_state(rig: Rig) -> None:
    rig.app.send(QUERY, {"correlation": "q0"})  # nothing ran yet: the robot knows no mission -1
    rig.app.wait(terminal("state", "q0"))
    assert rig.app.of("state", "q0")[0]["payload"]["state"] == "failed"
    rig.app.send(GOTO, {"correlation": "g", "payload": GOAL})
    rig.app.wait(terminal("feedback", "g"))
    rig.app.send(QUERY, {"correlation": "q1", "mission": 1})
    rig.app.send(QUERY, {"correlation": "q2"})  # the last mission
    rig.app.wait(terminal("state", "q1"))
    rig.app.wait(terminal("state", "q2"))
    for corr in ("q1", "q2"):
        (state,) = rig.app.of("state", corr)
        assert state["payload"]["state"] == "finished" and state["mission"] == 1


def test_invalid_events_are_answered_and_the_engine_carries_on(rig: Rig) -> None:
    cases: list[tuple[str, Any, str]] = [
        (GOTO, b"{not json", "invalid-json"),
        (GOTO, b"\xff\xfe", "invalid-json"),
        (GOTO, b'{"payload": NaN}', "invalid-event"),  # no ROS number holds it: named where it is
        (GOTO, {"correlation": "c1", "payload": {"procedure": {"goals": "north"}}}, "invalid-event"),
        (GOTO, {"correlation": "c2", "payload": GOAL, "colour": "red"}, "invalid-event"),
        (GOTO, {"correlation": "c3"}, "invalid-event"),
        (GOTO, {"correlation": "c4", "type": "cancel", "payload": GOAL}, "invalid-event"),
        (GOTO, {"correlation": "c5", "robot": "rb1_base_b", "payload": GOAL}, "invalid-event"),
        (CANCEL, {"correlation": "c6", "mission": "one"}, "invalid-event"),
        (GOTO, json.dumps({"payload": {"x": "y" * 70000}}).encode(), "too-large"),
        (f"td2adaptor/{ROBOT}/DoorComponent/door/write", {"payload": {"data": "open"}}, "invalid-event"),
        (f"td2adaptor/{ROBOT}/DoorComponent/door/write", [1, 2], "invalid-event"),
    ]
    for topic, event, _ in cases:
        rig.app.send(topic, event)
    rig.app.wait(lambda ev: len([e for _, e in ev if e.get("type") == "error"]) >= len(cases))
    errors = rig.app.of("error")
    assert [e["payload"]["code"] for e in errors] == [code for _, _, code in cases]
    by_corr = {e.get("correlation"): e for e in errors}
    assert by_corr["c1"]["payload"]["errors"][0]["path"] == "/payload/procedure/goals"
    assert "colour" in by_corr["c2"]["payload"]["message"]
    assert "rb1_base_b" in by_corr["c5"]["payload"]["message"]
    assert all(e["payload"]["topic"] for e in errors)
    assert rig.engine.stats["invalid"] == len(cases)
    rig.app.send(GOTO, {"correlation": "ok", "payload": GOAL})
    rig.app.wait(terminal("feedback", "ok"))


def test_redelivered_events_are_handled_once(rig: Rig) -> None:
    event = {"id": "same", "correlation": "dup", "payload": GOAL}
    rig.app.send(GOTO, event)
    rig.app.send(GOTO, event)
    rig.app.wait(terminal("feedback", "dup"))
    time.sleep(0.1)
    # run once; the redelivery is answered with the mission's last feedback event again (or, when it came
    # before any, by the first one): a repeat, the same event id
    events = rig.feedback("dup")
    once = list({e["id"]: e for e in events}.values())
    assert [e["payload"]["state"] for e in once] == ["queued", "running", "finished"]
    assert len(events) - len(once) <= 1 and all(e in once for e in events)
    rig.app.send(GOTO, event)  # once more, after the end: its terminal event again
    rig.app.wait(lambda _: len(rig.feedback("dup")) == len(events) + 1)
    assert rig.feedback("dup")[-1] == once[-1]
    assert rig.engine.stats["duplicates"] == 2 and not rig.app.of("error")
    # without an id, a repeated invoke of the mission in progress (same correlation) is recognised too
    rig.app.send(GOTO, {"correlation": "dup2", "payload": GOAL})
    rig.app.send(GOTO, {"correlation": "dup2", "payload": GOAL})
    rig.app.wait(terminal("feedback", "dup2"))
    time.sleep(0.1)
    assert [e["payload"]["state"] for e in rig.feedback("dup2")] == ["queued", "running", "finished"]
    assert rig.engine.stats["duplicates"] == 3 and not rig.app.of("error")


def test_mission_timeout_gives_failure_feedback_and_cancels_on_the_robot() -> None:
    r = Rig(duration=30.0, mission_timeout=0.3)
    try:
        started = time.monotonic()
        r.app.send(GOTO, {"correlation": "slow", "payload": GOAL})
        r.app.wait(terminal("feedback", "slow"))
        assert time.monotonic() - started < 2.0
        last = r.feedback("slow")[-1]["payload"]
        assert (last["state"], last["reason"]) == ("failed", "timeout")
        assert "mission timeout of 0.3 s" in last["message"] and "running" in last["message"]
        assert ("GoToComponent", "gotoCancel") in r.port.calls
        assert r.sim.components["GoToComponent"].active() is None
    finally:
        r.close()


def test_robot_gone_mid_mission_becomes_failure_feedback() -> None:
    r = Rig(duration=30.0, max_query_failures=3)
    try:
        r.app.send(GOTO, {"correlation": "lost", "payload": GOAL})
        r.app.wait(lambda ev: any(e.get("payload", {}).get("state") == "running" for _, e in ev))
        r.port.down = True
        r.app.wait(terminal("feedback", "lost"))
        last = r.feedback("lost")[-1]["payload"]
        assert (last["state"], last["reason"]) == ("failed", "unreachable")
        assert "did not answer 3 queries" in last["message"]
        # the start call itself failing
        r.app.send(PICK, {"correlation": "nopick", "payload": {"procedure": {"pick_frame_id": "c"}}})
        r.app.wait(terminal("feedback", "nopick"))
        (only,) = r.feedback("nopick")
        assert (only["payload"]["state"], only["payload"]["reason"]) == ("failed", "unreachable")
        assert "not available" in only["payload"]["message"]
    finally:
        r.close()


def test_robot_refusal_is_a_rejection_without_a_mission_id(rig: Rig) -> None:
    rig.sim.components["GoToComponent"].add({})  # someone else keeps the robot's GoTo busy
    rig.app.send(GOTO, {"correlation": "refused", "payload": GOAL})
    rig.app.wait(terminal("feedback", "refused"))
    (only,) = rig.feedback("refused")
    assert only["payload"]["reason"] == "rejected" and "mission" not in only
    assert "already running a procedure" in only["payload"]["message"]


class NoIdPort(SimPort):
    """A robot whose run response carries no mission id: the engine must fall back to -1."""

    queried: list[int]

    def start(self, component: str, action: str, payload: Any, timeout: float) -> StartResult:
        result = super().start(component, action, payload, timeout)
        response = json.loads(json.dumps(result.response))
        del response["state"]["header"]["id"]
        return StartResult(response, None)

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Any:
        self.queried.append(mission_id)
        return super().query(component, action, mission_id, timeout)


def test_query_falls_back_to_minus_one_only_without_an_id() -> None:
    broker = LocalBroker()
    model = rb1_model()
    port = NoIdPort(model, sim(0.2))
    port.queried = []
    app = LocalApp(broker)
    engine = serve(model, port, config(), broker=broker)
    try:
        app.send(GOTO, {"correlation": "noid", "payload": GOAL})
        app.wait(terminal("feedback", "noid"))
        assert set(port.queried) == {-1}
        assert app.of("feedback", "noid")[-1]["payload"]["state"] == "finished"
    finally:
        engine.stop()


def test_all_robots_channel_reaches_every_engine() -> None:
    broker = LocalBroker()
    model = rb1_model()
    app = LocalApp(broker)
    fleet = [config(robot=name) for name in ("rb1_base_a", "rb1_base_b")]
    engines = serve_fleet(model, lambda cfg: SimPort(model, sim(0.1, robot_id=cfg.robot)), fleet, broker=broker)
    assert engines[0].catalog is engines[1].catalog  # one TD, one catalog for the fleet: not a copy per robot
    try:
        app.send("td2adaptor/all/GoToComponent/gotoRun", {"correlation": "everyone", "payload": GOAL})
        app.wait(
            lambda ev: (
                {e["robot"] for _, e in ev if e.get("correlation") == "everyone" and e["payload"].get("terminal")}
                == {"rb1_base_a", "rb1_base_b"}
            )
        )
        app.send("td2adaptor/rb1_base_b/GoToComponent/gotoRun", {"correlation": "only-b", "payload": GOAL})
        app.wait(terminal("feedback", "only-b"))
        assert {e["robot"] for e in app.of("feedback", "only-b")} == {"rb1_base_b"}
    finally:
        for engine in engines:
            engine.stop()
    check_outbound(app.events)


def test_properties_are_throttled_retained_and_sent_on_change() -> None:
    r = Rig(duration=0.1, property_period=0.05)
    try:
        r.app.wait(lambda ev: any(e.get("affordance") == "poseMarker" for _, e in ev))
        r.app.send(GOTO, {"correlation": "to-cart", "payload": GOAL})
        r.app.wait(terminal("feedback", "to-cart"))
        r.app.wait(lambda ev: any(e.get("affordance") == "poseMarker" and e["payload"]["markers"] for _, e in ev))
        time.sleep(0.3)
        markers = [e["payload"]["markers"] for e in r.app.of("property") if e["affordance"] == "poseMarker"]
        assert [[m["id"] for m in ms] for ms in markers] == [[], [3]]  # unchanged values are not repeated
        late = LocalBus(r.broker, "late")  # a late subscriber reads the retained value
        got: list[Any] = []
        late.subscribe("td2adaptor/+/PoseMarkerComponent/poseMarker", lambda m: got.append(json.loads(m.payload)))
        late.connect()
        assert late.drain(5) and [m["id"] for m in got[-1]["payload"]["markers"]] == [3]
        late.close()
    finally:
        r.close()


def test_write_property_and_its_failure(rig: Rig) -> None:
    door = f"td2adaptor/{ROBOT}/DoorComponent/door/write"
    rig.app.send(door, {"payload": {"data": 1.0}})
    rig.app.bus.drain(5)
    deadline = time.monotonic() + 5
    while rig.sim.door_command is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert rig.sim.door_command == 1.0
    rig.port.down = True
    rig.app.send(door, {"correlation": "w", "payload": {"data": 0.0}})
    rig.app.wait(lambda ev: bool([e for _, e in ev if e.get("type") == "error"]))
    assert rig.app.of("error", "w")[0]["payload"]["code"] == "call-failed"


def test_a_thousand_malformed_events_are_each_answered(rig: Rig) -> None:
    for i in range(1000):
        rig.app.send(GOTO if i % 2 else QUERY, b"\x00garbage" if i % 3 else {"correlation": f"bad{i}", "payload": 1})
    rig.app.wait(lambda ev: sum(1 for _, e in ev if e.get("type") == "error") >= 1000, timeout=30)
    assert len(rig.app.of("error")) == 1000
    rig.app.send(GOTO, {"correlation": "alive", "payload": GOAL})
    rig.app.wait(terminal("feedback", "alive"))


def test_stop_publishes_offline_and_crash_leaves_the_will() -> None:
    broker = LocalBroker()
    model = rb1_model()
    app = LocalApp(broker, "td2adaptor/+/status")
    engine = serve(model, SimPort(model, sim()), config(), broker=broker)
    app.wait(lambda ev: [e["payload"]["state"] for _, e in ev] == ["online"])
    engine.stop()
    app.wait(lambda ev: [e["payload"]["state"] for _, e in ev] == ["online", "offline"])
    engine2 = Engine(model, SimPort(model, sim()), LocalBus(broker, "crashy"), config(robot="rb1_base_c"))
    bus = engine2.bus
    assert isinstance(bus, LocalBus)
    from td2adaptor.runtime.engine.engine import status_event

    bus.will = status_event(engine2.config, model, "offline")
    engine2.start()
    bus.crash()
    app.wait(lambda ev: any(e["robot"] == "rb1_base_c" and e["payload"]["state"] == "offline" for _, e in ev))


class RaisingPort(SimPort):
    """Like the generated components: a response saying `result: error` arrives as an exception carrying it."""

    def _check(self, response: Any) -> Any:
        if response["result"]["result"] == "error":
            raise PortCallFailed(f"robot says: {response['result']['message']}", response=response)
        return response

    def start(self, component: str, action: str, payload: Any, timeout: float) -> StartResult:
        result = super().start(component, action, payload, timeout)
        self._check(result.response)
        return result

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Any:
        return self._check(super().query(component, action, mission_id, timeout))


def test_robot_answers_carried_by_port_errors_are_read_as_answers() -> None:
    broker = LocalBroker()
    model = rb1_model()
    robot = sim(0.2)
    app = LocalApp(broker)
    engine = serve(model, RaisingPort(model, robot), config(), broker=broker)
    try:
        robot.components["GoToComponent"].add({})
        app.send(GOTO, {"correlation": "refused", "payload": GOAL})
        app.send(QUERY, {"correlation": "q", "mission": 99})
        app.wait(terminal("feedback", "refused"))
        app.wait(terminal("state", "q"))
        (refused,) = app.of("feedback", "refused")
        assert refused["payload"]["reason"] == "rejected" and "already running" in refused["payload"]["message"]
        (state,) = app.of("state", "q")
        assert state["payload"]["state"] == "failed" and "no procedure with id 99" in state["payload"]["message"]
        assert not app.of("error")
    finally:
        engine.stop()
    check_outbound(app.events)
