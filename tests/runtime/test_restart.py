"""Missions outlive the edge node (issue 30, item 6): a node started again on the same state directory follows
each procedure mission the last run left in flight to its end, ends every other one `failed` with words that
say the node restarted, and answers an invoke sent again under its id. In process, on the local bus and the
simulated RB-1 (the robot keeps running while the node is away); the real kill (SIGKILL of `td2adaptor run`
over mosquitto and ROS 2) is test_edge_node_restart_ros2.py."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.engine.ledger import SEQ_BLOCK, Ledger
from td2adaptor.runtime.engine.replay import now_text
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_model, sim, terminal

ROBOT = "rb1_base_a"
GOTO = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"


def _config(state: Path, **kw: Any) -> RuntimeConfig:
    base: dict[str, Any] = {"robot": ROBOT, "poll_period": 0.02, "property_period": 0, "call_timeout": 1.0}
    return RuntimeConfig(**{**base, "state_dir": str(state), **kw})


def _once(events: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The events by id, each once (an event answered again is the same event: the same id)."""
    return list({e["id"]: e for e in events}.values())


def test_a_mission_in_flight_is_followed_to_its_end_by_the_restarted_node(tmp_path: Path) -> None:
    broker, model, robot = LocalBroker(), rb1_model(), sim(1.0)
    app = LocalApp(broker)
    invoke = {"id": "go-1", "correlation": "go-1", "time": now_text(), "payload": GOAL}
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:
        app.send(GOTO, invoke)
        app.wait(lambda _: any(e["payload"]["state"] == "running" for e in app.of("feedback", "go-1")))
    finally:
        engine.stop()  # the node goes away; the robot goes on
    assert not any(e["payload"]["terminal"] for e in app.of("feedback", "go-1"))
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:
        app.send(GOTO, invoke)  # sent again while the mission runs: its current state again
        app.wait(terminal("feedback", "go-1"))
        assert engine.stats.get("resumed") == 1
        time.sleep(0.2)
        events = app.of("feedback", "go-1")
        once = _once(events)
        assert [e["payload"]["state"] for e in once] == ["queued", "running", "finished"]
        assert [e["payload"]["seq"] for e in once] == [1, 2, 3]
        assert sum(e["payload"]["terminal"] for e in once) == 1
        assert len(events) == len(once) + 1 and events[2] == once[1]  # the answer: the running event again
        assert len({e["mission"] for e in once}) == 1
        app.send(GOTO, invoke)  # after the end: the terminal event again
        app.wait(lambda _: len(app.of("feedback", "go-1")) == len(events) + 1)
        assert app.of("feedback", "go-1")[-1] == once[-1]
        # the component is free: the next mission runs
        app.send(GOTO, {"id": "go-2", "correlation": "go-2", "time": now_text(), "payload": GOAL})
        app.wait(terminal("feedback", "go-2"), timeout=10)
        assert app.of("feedback", "go-2")[-1]["payload"]["state"] == "finished"
    finally:
        engine.stop()
    check_outbound(app.events)


def test_what_cannot_be_followed_on_ends_failed_once_and_an_unsent_end_is_sent(tmp_path: Path) -> None:
    """What the last run left in the ledger, written as it writes it: a goal, a call, an invoke the robot had
    not answered, a terminal event stored but maybe not sent. Each gets exactly one terminal event, also
    across a second restart."""
    ledger = Ledger(_config(tmp_path).ids_file, keep=330)
    topic = GOTO

    def row(kind: str, action: str, component: str, correlation: str) -> str:
        return ledger.open(
            event_id=correlation, topic=topic, kind=kind, component=component, action=action, correlation=correlation
        )

    # a procedure the robot had not answered yet
    row("procedure", "gotoRun", "GoToComponent", "unanswered")
    # a mission without a mission id, running
    blind = row("procedure", "gotoRun", "GoToComponent", "blind")
    running = {"type": "feedback", "affordance": "gotoRun", "robot": ROBOT, "id": "e-1", "time": now_text()}
    running.update(source="x", correlation="blind", payload={"state": "running", "terminal": False, "seq": 2})
    ledger.event(
        blind, mission=None, goal=None, state="running", seq=2, reserved=2, latest=json.dumps(running), terminal=False
    )
    # a goal-like mission with feedback numbers reserved ahead (its kind is all recovery looks at)
    goal = row("goal", "gotoRun", "GoToComponent", "goal")
    ledger.event(goal, mission=None, goal="ab" * 16, state="running", seq=2, reserved=2, latest="{}", terminal=False)
    ledger.reserve(goal, 3 + SEQ_BLOCK)
    # an end stored, not marked sent
    ended = row("procedure", "gotoRun", "GoToComponent", "ended")
    end = {**running, "id": "e-9", "correlation": "ended", "payload": {"state": "finished", "terminal": True, "seq": 3}}
    ledger.event(
        ended, mission=7, goal=None, state="finished", seq=3, reserved=3, latest=json.dumps(end), terminal=True
    )
    ledger.close()
    # a mission with an id, started longer ago than the mission timeout: not followed (nor cancelled: its id
    # may name another mission by now)
    old = Ledger(_config(tmp_path).ids_file, keep=330, clock=lambda: time.time() - 1000)
    stale = old.open(
        event_id="stale",
        topic=topic,
        kind="procedure",
        component="GoToComponent",
        action="gotoRun",
        correlation="stale",
    )
    old.event(stale, mission=1, goal=None, state="running", seq=2, reserved=2, latest="{}", terminal=False)
    old.close()

    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    for _ in range(2):  # the second start finds nothing left to do
        engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
        engine.stop()
    assert app.bus.drain(30.0)  # the local broker delivers on its own thread: every event published has come
    terminals = {
        c: [e for e in app.of("feedback", c) if e["payload"]["terminal"]]
        for c in ("unanswered", "blind", "goal", "ended", "stale")
    }
    assert {c: len(t) for c, t in terminals.items()} == {"unanswered": 1, "blind": 1, "goal": 1, "ended": 1, "stale": 1}
    assert terminals["ended"][0] == end  # sent again as it was
    for correlation in ("unanswered", "blind", "goal", "stale"):
        payload = terminals[correlation][0]["payload"]
        assert (payload["state"], payload["reason"]) == ("failed", "unreachable")
        assert payload["message"].startswith("the edge node restarted"), payload
    assert "unknown" in terminals["goal"][0]["payload"]["message"]
    assert "before the robot answered" in terminals["unanswered"][0]["payload"]["message"]
    assert "timeout of 600 s had passed" in terminals["stale"][0]["payload"]["message"]
    assert terminals["blind"][0]["payload"]["seq"] == 3
    assert terminals["goal"][0]["payload"]["seq"] == 3 + SEQ_BLOCK + 1  # past every number it may have used
    assert terminals["goal"][0]["payload"]["goal"] == "ab" * 16
    assert (robot.x, robot.y) == (0.0, 0.0)  # nothing ran again


def test_the_replay_guard_and_the_ledger_share_one_connection_to_the_robots_file(tmp_path: Path) -> None:
    """A SQLite connection costs about 120 KiB, and a fleet process holds its robots' files open: the guard and the
    ledger use one connection (one open descriptor of the file), not one each; closed when the engine stops."""
    import os

    broker, model = LocalBroker(), rb1_model()
    config = _config(tmp_path)

    def opened() -> int:
        fds = Path("/proc/self/fd")
        return sum(1 for fd in fds.iterdir() if os.path.realpath(fd) == os.path.realpath(config.ids_file))

    engine = serve(model, SimPort(model, sim(0.2)), config, broker=broker)
    try:
        assert opened() == 1
    finally:
        engine.stop()
    assert opened() == 0
