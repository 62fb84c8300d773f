"""Faults and load for the edge node (ROS-free, to stay fast: the simulated robot behind a `SimPort`).

* 10,000 malformed events of every kind on every inbound topic, through the in-process bus: each one is
  answered by exactly one error event and the engine goes on serving (the MQTT path of the same is
  test_runtime_mqtt's 1,000-event test; 10,000 over the local bus keep this test at a few seconds).
* 3 robots × 100 missions each over a real mosquitto, one edge process (serve_fleet): no feedback lost —
  every mission's feedback is numbered 1..n without a gap and ends in exactly one terminal event.

The ROS-backed faults (robot killed mid-mission, broker restart mid-mission) are in test_edge_node_ros2.py.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Any

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve, serve_fleet
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import Recorder
from tests.runtime.rb1 import GOAL, check_outbound, rb1_model, sim, terminal

ROBOT = "rb1_fault"


def malformed(i: int, robot: str) -> tuple[str, bytes]:
    """The i-th of ten kinds of broken events, on one of the robot's inbound topics."""
    topics = [
        f"td2adaptor/{robot}/GoToComponent/gotoRun",
        f"td2adaptor/{robot}/GoToComponent/gotoQuery",
        f"td2adaptor/{robot}/PickComponent/pickCancel",
        f"td2adaptor/{robot}/DoorComponent/door/write",
        "td2adaptor/all/PlaceComponent/placeRun",
    ]
    corr = f"bad-{i}"
    kinds: list[bytes] = [
        b"{oops",
        b"\xff\xfe\x00 not utf-8",
        b"[" * 1500 + b"]" * 1500,  # nesting deeper than the JSON parser follows (RecursionError)
        json.dumps({"correlation": corr, "payload": 1}).encode(),
        json.dumps({"correlation": corr, "robot": "someone_else", "payload": {}}).encode(),
        json.dumps({"correlation": corr, "mission": "seven", "payload": {}}).encode(),
        json.dumps({"correlation": corr, "type": "feedback", "payload": {}}).encode(),  # not an inbound type
        b'{"payload": NaN}',
        b"x" * 5000,  # larger than max_event_bytes below
        json.dumps(["not", "an", "object"]).encode(),
    ]
    return topics[i % len(topics)], kinds[(i // len(topics)) % len(kinds)]


def test_ten_thousand_malformed_events_are_each_answered_and_the_engine_carries_on() -> None:
    broker = LocalBroker()
    model = rb1_model()
    app = Recorder(broker, [f"td2adaptor/{ROBOT}/error", f"td2adaptor/{ROBOT}/+/+/feedback"])
    config = RuntimeConfig(robot=ROBOT, poll_period=0.02, property_period=0, max_event_bytes=4096)
    engine = serve(model, SimPort(model, sim(0.1)), config, broker=broker)
    try:
        begin = time.monotonic()
        for i in range(10_000):
            app.send(*malformed(i, ROBOT))
        app.wait(lambda ev: sum(1 for _, e in ev if e.get("type") == "error") >= 10_000, timeout=60)
        elapsed = time.monotonic() - begin
        errors = app.of("error")
        assert len(errors) == 10_000  # each answered, once
        codes = {e["payload"]["code"] for e in errors}
        assert codes == {"invalid-json", "invalid-event", "too-large"}, codes
        salvaged = [e for e in errors if str(e.get("correlation", "")).startswith("bad-")]
        assert len(salvaged) == 4_000  # the four kinds that carry a readable correlation keep it
        assert engine.stats["invalid"] == 10_000 and engine.stats["in"] == 10_000
        assert all(t.is_alive() for t in engine._threads)
        # still serving: a valid mission afterwards runs to its end
        alive = json.dumps({"correlation": "alive", "payload": GOAL}).encode()
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", alive)
        app.wait(terminal("feedback", "alive"))
        assert app.of("feedback")[-1]["payload"]["state"] == "finished"
        print(f"10,000 malformed events answered in {elapsed:.1f} s ({10_000 / elapsed:.0f}/s)")
    finally:
        engine.stop()
        app.close()
    check_outbound(app.events)


def test_three_robots_times_a_hundred_missions_lose_no_feedback(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    robots = ["fleet_a", "fleet_b", "fleet_c"]
    model = rb1_model()
    configs = [
        RuntimeConfig(robot=r, bus=broker.url, poll_period=0.005, property_period=0, call_timeout=2.0) for r in robots
    ]
    sims = {r: sim(0.02, queue_time=0.005) for r in robots}
    engines = serve_fleet(model, lambda c: SimPort(model, sims[c.robot]), configs)
    app = AppClient(broker.url, ["td2adaptor/+/GoToComponent/gotoRun/feedback"], client_id="hundreds-app")
    failures: list[str] = []

    def drive(robot: str) -> None:
        for n in range(100):
            correlation = f"{robot}-{n}"
            app.send(f"td2adaptor/{robot}/GoToComponent/gotoRun", {"correlation": correlation, "payload": GOAL})
            try:
                app.wait(terminal("feedback", correlation), timeout=20)
            except AssertionError as exc:
                failures.append(f"{correlation}: {exc}")
                return

    try:
        begin = time.monotonic()
        drivers = [threading.Thread(target=drive, args=(r,)) for r in robots]
        for d in drivers:
            d.start()
        for d in drivers:
            d.join(120)
        elapsed = time.monotonic() - begin
        assert not failures, failures[:3]
    finally:
        for engine in engines:
            engine.stop()
        app.close()
        broker.stop()
    by_mission: dict[str, list[dict[str, Any]]] = {}
    for _, event in app.events:
        by_mission.setdefault(event["correlation"], []).append(event)
    assert len(by_mission) == 300
    sent = sum(engine.stats.get("out.feedback", 0) for engine in engines)
    unique = {e["id"] for _, e in app.events}
    assert len(unique) == sent  # every feedback event any engine published arrived (redeliveries aside)
    for correlation, events in by_mission.items():
        events = sorted({e["id"]: e for e in events}.values(), key=lambda e: e["payload"]["seq"])
        states = [e["payload"]["state"] for e in events]
        assert [e["payload"]["seq"] for e in events] == list(range(1, len(events) + 1)), (correlation, states)
        assert [e["payload"]["terminal"] for e in events] == [False] * (len(events) - 1) + [True]
        assert states[0] == "queued" and states[-1] == "finished" and len(set(states)) == len(states), states
        assert len({e["mission"] for e in events}) == 1
    per_robot = {r: sum(1 for c in by_mission if c.startswith(r)) for r in robots}
    assert per_robot == {r: 100 for r in robots}
    print(f"300 missions, {sent} feedback events, none lost, in {elapsed:.1f} s")
