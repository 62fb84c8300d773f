"""A procedure mission's state machine (engine/procedure.py) where its events meet a robot call in flight: a
cancel event during the run call, the mission timeout during a query. On the in-process bus with the simulated
RB-1, whose calls are slowed down so that the event surely comes while the call waits."""

from __future__ import annotations

import time
from typing import Any

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.edge import until
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_model, sim, terminal

ROBOT = "machine_bot"
GOTO = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"
CANCEL = f"td2adaptor/{ROBOT}/GoToComponent/gotoCancel"


def rig(duration: float, **cfg: Any) -> tuple[LocalApp, SimPort, Any]:
    broker = LocalBroker()
    model = rb1_model()
    port = SimPort(model, sim(duration, robot_id=ROBOT))
    app = LocalApp(broker)
    base: dict[str, Any] = {"robot": ROBOT, "poll_period": 0.02, "property_period": 0, "state_dir": ""}
    engine = serve(model, port, RuntimeConfig(**{**base, **cfg}), broker=broker)
    return app, port, engine


def test_a_cancel_during_the_run_call_is_carried_out_once_the_robot_answered_it() -> None:
    app, port, engine = rig(30.0, call_timeout=5.0)
    try:
        port.delay = 0.5  # every call of the robot takes half a second
        app.send(GOTO, {"correlation": "m", "payload": GOAL})
        assert until(lambda: ("GoToComponent", "gotoRun") in port.calls, 10)  # the run call is in flight
        app.send(CANCEL, {"correlation": "c"})
        app.wait(terminal("feedback", "m"), 15)
        states = [e["payload"]["state"] for e in app.of("feedback", "m")]
        assert states[0] == "queued" and states[-1] == "cancelled" and states.count("cancelled") == 1
        (answer,) = app.of("state", "c")
        assert answer["payload"]["state"] == "cancelled" and answer["mission"] == 1
        # the cancel went to the robot right after the run call: no query came between them
        assert [a for _, a in port.calls][:2] == ["gotoRun", "gotoCancel"]
    finally:
        engine.stop()
    check_outbound(app.events)


def test_the_mission_timeout_during_a_query_ends_it_once_the_query_is_answered() -> None:
    app, port, engine = rig(30.0, call_timeout=5.0, mission_timeout=0.6)
    try:
        app.send(GOTO, {"correlation": "m", "payload": GOAL})
        app.wait(lambda ev: any(e.get("payload", {}).get("state") == "running" for _, e in ev), 10)
        port.delay = 1.0  # the next query is still in flight when the mission timeout passes
        begin = time.monotonic()
        app.wait(terminal("feedback", "m"), 15)
        assert time.monotonic() - begin >= 0.4  # not before that query's answer
        ends = [e["payload"] for e in app.of("feedback", "m") if e["payload"]["terminal"]]
        assert [(p["state"], p["reason"]) for p in ends] == [("failed", "timeout")]
        assert "mission timeout of 0.6 s" in ends[0]["message"]
        assert port.calls[-1] == ("GoToComponent", "gotoCancel")  # the robot was asked to stop it
    finally:
        engine.stop()
    check_outbound(app.events)
