"""The edge node serving a TD action bound to a ROS 2 action, on real ROS 2 Jazzy over a real mosquitto.

The robot is `tests.runtime.fibo_ros2` (an rclpy ActionServer of test_msgs/action/Fibonacci) in its own
process, the edge node is `connect` + `serve` in this process on the rclpy adaptor generated from
tests.lowering.test_actions.action_td. Checked: invoke → the acceptance, one feedback event per ROS feedback
message (in order, carrying it) → exactly one terminal event with the result; rejected and aborted goals;
query and cancel; the throttle; the action server killed mid-goal → failure within `action_server_timeout`,
the component free again; a burst of 1,000 feedback messages relayed in order, without a gap or a duplicate;
the edge process's threads the same with eight goals in flight as with none; a goal's events going out while the
engine's loop is busy.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.model import Model
from td2adaptor.model.events import Kind, build_catalog
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime import RuntimeConfig, loop, serve
from td2adaptor.runtime.events import EventValidator
from td2adaptor.runtime.node.roslink import RosLink, connect
from tests.lowering.test_actions import INTERFACES, action_td
from tests.ros2 import env
from tests.ros2.common import Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, Event
from tests.runtime.edge import feedback, until
from tests.runtime.edge import rejects as edge_rejects
from tests.runtime.fibo_ros2 import ABORT, BURST, SLOW, sequence
from tests.runtime.rb1 import terminal
from tests.runtime.rclpy_robot import generate_rclpy

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOT = "fibo_edge"
KILLED = "fibo_killed"
COMPONENT = "MathComponent"


def topic(robot: str, suffix: str = "") -> str:
    return f"td2adaptor/{robot}/{COMPONENT}/fibonacci{suffix}"


@pytest.fixture(scope="module")
def fibo_build(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path]:
    """The model and the generated rclpy adaptor's source folder (it goes on sys.path)."""
    model, src, _ = generate_rclpy(action_td(), INTERFACES, tmp_path_factory.mktemp("fibo-edge"))
    return model, src


def robot_process(*namespaces: str) -> Process:
    process = Process([sys.executable, "-m", "tests.runtime.fibo_ros2", *namespaces], env.child_env([]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
    except BaseException:
        process.stop()
        raise
    return process


@pytest.fixture(scope="module")
def fibo_robot(ros2_domain: int) -> Iterator[Process]:
    process = robot_process(ROBOT)
    yield process
    process.stop()


class Edge:
    """An edge node for `robot` on ROS 2 and mosquitto, and an application recording its events."""

    def __init__(self, build: tuple[Model, Path], broker: Mosquitto, robot: str, **config: Any) -> None:
        model, src = build
        self.model = model
        settings: dict[str, Any] = {"poll_period": 0.1, "call_timeout": 15.0, "mission_timeout": 60.0}
        settings.update(config)
        self.config = RuntimeConfig(robot=robot, bus=broker.url, property_period=0, state_dir="", **settings)
        self.link: RosLink = connect(model, model.package_name, [self.config], ros=2, package_paths=[src])
        port = self.link.ports[robot]
        # the goal service can be discovered before its server matched our response reader (the first answer
        # may be lost): wait for one answered goal; a negative order is rejected, so nothing runs
        assert until(lambda: rejects(port), 30, 0.1)
        self.engine = serve(model, port, self.config)
        self.app = AppClient(broker.url, [f"td2adaptor/{robot}/#"])
        self.validator = EventValidator(build_catalog(model))
        self.catalog = build_catalog(model)

    def send(self, suffix: str, event: dict[str, Any]) -> None:
        self.app.send(topic(self.config.robot, suffix), {"source": "test", **event})

    def ended(self, correlation: str, timeout: float = 30.0) -> list[dict[str, Any]]:
        """The goal's feedback events once its terminal one came; all conform to their schema."""
        self.app.wait(terminal("feedback", correlation), timeout=timeout)
        events = feedback(self.app.events, correlation)
        self.check(self.app.events)
        return events

    def check(self, events: list[Event]) -> None:
        for where, event in events:
            if self.catalog.route(where) is not None or where.endswith("/td") or f"/{WOT_LEVEL}/" in where:
                continue  # sent by the test, the robot's TD, or the WoT consumers' form of an event
            kind = Kind(event["type"])
            spec = self.catalog.find(kind, event.get("affordance") if kind not in (Kind.ERROR, Kind.STATUS) else None)
            assert spec.topic(event["robot"]) == where
            assert self.validator.errors(spec, event) == [], (where, event)

    def answers(self, correlation: str, timeout: float = 10.0) -> list[dict[str, Any]]:
        """The state or error events answering the test's query or cancel `correlation` (at least one)."""

        def found(events: list[Event]) -> list[dict[str, Any]]:
            return [e for _, e in events if e.get("correlation") == correlation and e.get("type") in ("state", "error")]

        return found(self.app.wait(lambda ev: bool(found(ev)), timeout=timeout))

    def close(self) -> None:
        self.app.close()
        self.engine.stop()
        self.link.close()


def rejects(port: Any) -> bool:
    """A goal of order -1 is rejected: the server is there and its answers reach us."""
    return edge_rejects(port, COMPONENT, "fibonacci", {"order": -1})


def sent_feedback(robot: Process, ns: str, order: int) -> list[list[int]]:
    """The feedback messages the robot sent for its goal of `order` (waits for the goal's end)."""
    robot.seen.clear()
    robot.wait_for(lambda e: e.get("event") == "goal" and e.get("ns") == ns and e.get("order") == order, timeout=10)
    robot.seen.clear()
    robot.wait_for(lambda e: e.get("event") == "end" and e.get("ns") == ns, timeout=10)
    return [e["sequence"] for e in robot.seen if e.get("event") == "feedback" and e.get("ns") == ns]


def check_goal(events: list[dict[str, Any]], messages: list[list[int]], end: str) -> dict[str, Any]:
    """accepted, then one running event per ROS feedback message (carrying it, in order), then one terminal."""
    payloads = [e["payload"] for e in events]
    assert [p["seq"] for p in payloads] == list(range(1, len(payloads) + 1))
    assert [p["terminal"] for p in payloads] == [False] * (len(payloads) - 1) + [True]
    assert (payloads[0]["state"], payloads[0]["result"]) == ("queued", "accepted")
    assert [p["feedback"]["sequence"] for p in payloads[1:-1]] == messages
    assert all(p["state"] == "running" for p in payloads[1:-1])
    # a running event says a running word, also when the result came first: the end only in the terminal event
    assert all(p["result"] in ("executing", "canceling") for p in payloads[1:-1]), payloads
    assert len({p["goal"] for p in payloads}) == 1 and len(payloads[0]["goal"]) == 32
    assert payloads[-1]["state"] == end
    return payloads[-1]


def test_goal_feedback_and_result_over_mqtt(
    fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto
) -> None:
    edge = Edge(fibo_build, broker, ROBOT)
    try:
        edge.send("", {"id": "g-5", "correlation": "five", "payload": {"order": 5}})
        events = edge.ended("five")
        last = check_goal(events, sent_feedback(fibo_robot, ROBOT, 5), "finished")
        assert len(events) == 5 + 2
        assert (last["result"], last["output"]) == ("succeeded", {"sequence": sequence(5)})

        # rejected: the server refuses the goal; one terminal event in the robot's words
        edge.send("", {"correlation": "neg", "payload": {"order": -1}})
        (refused,) = edge.ended("neg")
        assert refused["payload"]["state"] == "failed" and refused["payload"]["terminal"]
        assert (refused["payload"]["reason"], refused["payload"]["result"]) == ("rejected", "rejected")
        assert refused["payload"]["message"] == "the goal was rejected"

        # aborted after two feedback messages: failed (aborted), with the result the server sent
        edge.send("", {"correlation": "abort", "payload": {"order": ABORT}})
        events = edge.ended("abort")
        last = check_goal(events, [sequence(1), sequence(2)], "failed")
        assert (last["reason"], last["result"], last["output"]) == ("aborted", "aborted", {"sequence": sequence(2)})
        # a query after the end answers with the end
        edge.send("/query", {"correlation": "q-end"})
        (answer,) = edge.answers("q-end")
        assert answer["type"] == "state" and answer["payload"]["state"] == "failed"
        assert answer["payload"]["goal"] == last["goal"]
    finally:
        edge.close()


def test_query_and_cancel_a_goal(fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto) -> None:
    edge = Edge(fibo_build, broker, ROBOT)
    try:
        edge.send("", {"correlation": "slow", "payload": {"order": SLOW}})
        edge.app.wait(lambda ev: any("feedback" in e["payload"] for e in feedback(ev, "slow")), timeout=20)
        goal = feedback(edge.app.events, "slow")[0]["payload"]["goal"]
        # a second invoke while the goal runs: busy, never queued
        edge.send("", {"correlation": "second", "payload": {"order": 3}})
        (busy,) = edge.ended("second")
        assert busy["payload"]["reason"] == "busy"
        edge.send("/query", {"correlation": "q", "payload": {"goal": goal}})
        (state,) = edge.answers("q")
        assert (state["type"], state["payload"]["state"], state["payload"]["goal"]) == ("state", "running", goal)
        assert state["payload"]["result"] == "executing" and not state["payload"]["terminal"]
        edge.send("/cancel", {"correlation": "c"})
        events = edge.ended("slow")
        assert events[-1]["payload"]["state"] == "cancelled" and events[-1]["payload"]["result"] == "canceled"
        assert [e["payload"]["state"] for e in events[1:-1]] == ["running"] * (len(events) - 2)
        answers = edge.answers("c")
        assert all(e["type"] == "state" and e["payload"]["goal"] == goal for e in answers)
        # a cancel of a goal nobody follows: an error event, not a silent drop
        edge.send("/cancel", {"correlation": "c2", "payload": {"goal": "0" * 32}})
        (error,) = edge.answers("c2")
        assert error["type"] == "error" and error["payload"]["code"] == "unsupported"
        edge.check(edge.app.events)
    finally:
        edge.close()


def test_a_goals_events_go_out_while_the_engine_loop_is_busy(
    fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto
) -> None:
    """A goal's feedback and end are published from the thread ROS tells them in, not queued behind the engine's
    loop (issue 31: the first feedback waited for the loop to wake and to finish the acceptance): with the loop
    held busy, a running goal's feedback events and its terminal event still come, in order."""
    edge = Edge(fibo_build, broker, ROBOT)
    shared = loop.acquire()  # the process's loop, which the edge node's engine runs on
    free = threading.Event()
    try:
        edge.send("", {"correlation": "busy-loop", "payload": {"order": 6}})
        edge.app.wait(lambda ev: bool(feedback(ev, "busy-loop")), timeout=20)  # queued: the goal was sent
        held = threading.Event()

        def hold() -> None:  # on the loop: nothing else runs there until `free`
            held.set()
            free.wait(60)

        shared.loop.post(hold)
        assert held.wait(10)
        events = edge.ended("busy-loop")
        assert not free.is_set()  # the loop was busy all along
        check_goal(events, sent_feedback(fibo_robot, ROBOT, 6), "finished")
    finally:
        free.set()
        loop.release(shared)
        edge.close()


def test_feedback_throttle(fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto) -> None:
    edge = Edge(fibo_build, broker, ROBOT, feedback_period=0.3)
    try:
        edge.send("", {"correlation": "t", "payload": {"order": 20}})
        events = edge.ended("t")
        messages = sent_feedback(fibo_robot, ROBOT, 20)
        relayed = [e["payload"]["feedback"]["sequence"] for e in events[1:-1]]
        # 20 messages 0.05 s apart, at most one event per 0.3 s: fewer events, in order, the last one kept
        assert len(messages) == 20 and 1 <= len(relayed) < len(messages)
        assert relayed[-1] == messages[-1] and relayed == sorted(relayed, key=len)
        assert events[-1]["payload"]["state"] == "finished"
        # the last message is held until the result came, and still sent as a running one
        assert [(e["payload"]["state"], e["payload"]["result"]) for e in events[1:-1]] == [
            ("running", "executing")
        ] * len(relayed), events
    finally:
        edge.close()


def test_a_server_killed_mid_goal_fails_it_within_the_bound_and_frees_the_component(
    fibo_build: tuple[Model, Path], broker: Mosquitto
) -> None:
    """The action server's process killed (SIGKILL) mid-goal: discovery would notice only after the lease (20 s
    with Fast DDS), the mission timeout after a minute; the goal ends `failed`/`unreachable` within
    `action_server_timeout`, a cancel and a query sent meanwhile are answered, and so are they after; the
    component is free again: a goal to the restarted server succeeds."""
    robot = robot_process(KILLED)
    edge = Edge(fibo_build, broker, KILLED, mission_timeout=60.0, call_timeout=15.0)
    bound = edge.config.action_server_timeout
    assert bound <= 3.0  # the default
    try:
        edge.send("", {"correlation": "k", "payload": {"order": SLOW}})
        edge.app.wait(lambda ev: any("feedback" in e["payload"] for e in feedback(ev, "k")), timeout=20)
        goal = feedback(edge.app.events, "k")[0]["payload"]["goal"]
        robot.proc.send_signal(signal.SIGKILL)
        robot.proc.wait(10)
        killed = time.monotonic()
        edge.send("/cancel", {"correlation": "c-during"})
        edge.send("/query", {"correlation": "q-during"})
        events = edge.ended("k", timeout=bound + 10.0)
        took = time.monotonic() - killed
        last = events[-1]["payload"]
        assert (last["state"], last["reason"]) == ("failed", "unreachable"), last
        assert "action server went away" in last["message"], last
        assert took < bound + 2.0, took  # the last feedback came before the kill: at most the bound after it
        assert sum(1 for e in events if e["payload"]["terminal"]) == 1
        assert edge.answers("q-during")[0]["type"] == "state"
        assert edge.answers("c-during", timeout=bound + 10.0)  # an error (the server is gone) or the end
        # after the end: a query and a cancel are answered with it
        edge.send("/query", {"correlation": "q-after"})
        edge.send("/cancel", {"correlation": "c-after"})
        for correlation in ("q-after", "c-after"):
            (answer,) = edge.answers(correlation)
            assert answer["type"] == "state", answer
            assert (answer["payload"]["state"], answer["payload"]["goal"]) == ("failed", goal)

        # the component is free: a goal to the restarted server runs to its end
        robot.stop()
        robot = robot_process(KILLED)
        # the dead server's endpoints stay in the graph until its lease ends: a goal sent before the new server
        # was discovered would go to the dead one only; wait for an answered goal, as the edge's start does
        assert until(lambda: rejects(edge.link.ports[KILLED]), 30, 0.1)

        # and for the node's presence to see the server again where it saw it gone (the killed process's node may
        # leave its graph before the lease ends): until its next look (`presence_period`) it answers an invoke
        # `absent` at once (the status is published when it changes; the kill was seconds ago)
        def present() -> bool:
            statuses = [e for t, e in edge.app.events if t.endswith("/status")]
            return bool(statuses) and statuses[-1]["payload"].get("robot") == "present"

        assert until(present, 30, 0.1), [e for t, e in edge.app.events if t.endswith("/status")][-3:]
        # even so, on a loaded machine a goal may go to the dead server's endpoints only: the component is free
        # when a goal sent again runs to its end; every goal gets its one terminal event either way
        ends = []
        for attempt in range(3):
            edge.send("", {"correlation": f"again-{attempt}", "payload": {"order": 3}})
            events = edge.ended(f"again-{attempt}", timeout=30)
            ends.append(events[-1]["payload"])
            if ends[-1]["state"] == "finished":
                break
            assert (ends[-1]["state"], ends[-1]["reason"]) == ("failed", "unreachable"), ends
        # (its feedback is checked against the robot's by the other tests: here the robot's own event lines of this
        # goal were once not seen within 10 s although the node relayed the goal to its end)
        print(f"goals after the restart: {[(e['state'], e.get('reason'), e.get('message')) for e in ends]}")
        assert ends[-1]["state"] == "finished", ends
        assert ends[-1]["output"] == {"sequence": sequence(3)}, ends
        edge.check(edge.app.events)
    finally:
        edge.close()
        robot.stop()


def test_a_wot_consumer_sends_a_goal_queries_and_cancels_it(
    fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto
) -> None:
    """The same goal through the WoT consumers' topics (the TD's forms): the goal's fields plus correlationId in,
    its feedback out; query and cancel on topics of their own, naming the goal."""
    edge = Edge(fibo_build, broker, ROBOT)
    wot = f"td2adaptor/{ROBOT}/{WOT_LEVEL}/{COMPONENT}/fibonacci"

    def of(suffix: str, correlation: str) -> list[dict[str, Any]]:
        return [e for t, e in edge.app.events if t == wot + suffix and e.get("correlationId") == correlation]

    try:
        edge.app.send(wot, {"order": SLOW, "correlationId": "w"})
        edge.app.wait(lambda _: any("feedback" in e for e in of("/feedback", "w")), timeout=20)
        goal = of("/feedback", "w")[0]["goal"]
        edge.app.send(wot + "/query", {"goal": goal, "correlationId": "wq"})
        edge.app.wait(lambda _: bool(of("/state", "wq")), timeout=10)
        assert of("/state", "wq")[0]["state"] == "running"
        edge.app.send(wot + "/cancel", {"correlationId": "wc"})
        edge.app.wait(lambda _: any(e["terminal"] for e in of("/feedback", "w")), timeout=20)
        assert [e["state"] for e in of("/feedback", "w") if e["terminal"]] == ["cancelled"]
    finally:
        edge.close()


def test_a_burst_of_a_thousand_feedback_messages_is_relayed_in_order_without_a_gap_or_a_duplicate(
    fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto
) -> None:
    """The server publishes 1,000 feedback messages back to back (each one different: [i]), then its result: one
    feedback event per message, in the order sent, none twice, none missing, then the terminal event."""
    edge = Edge(fibo_build, broker, ROBOT)
    try:
        edge.send("", {"correlation": "burst", "payload": {"order": BURST + 1000}})
        events = edge.ended("burst", timeout=60)
        fibo_robot.wait_for(lambda e: e.get("event") == "burst" and e.get("ns") == ROBOT, timeout=10)
        relayed = [e["payload"].get("feedback", {}).get("sequence") for e in events[1:-1]]
        missing = sorted({i for i in range(1, 1001)} - {r[0] for r in relayed if r})
        assert len(relayed) == 1000 and not missing, (len(relayed), missing[:20])
        last = check_goal(events, [[i] for i in range(1, 1001)], "finished")
        assert last["output"] == {"sequence": [1000]}
        assert len({e["id"] for e in events}) == len(events) == 1002  # no event twice either
    finally:
        edge.close()


def goal_threads() -> dict[str, int]:
    """This process's threads by name (without the number a thread pool gives each)."""
    names: dict[str, int] = {}
    for thread in threading.enumerate():
        name = thread.name.rstrip("0123456789")
        names[name] = names.get(name, 0) + 1
    return names


def test_the_edge_process_has_as_many_threads_with_eight_goals_in_flight_as_with_none(
    fibo_build: tuple[Model, Path], broker: Mosquitto
) -> None:
    """Eight robots of one edge node, each with a ROS 2 action goal in flight on a real action server: the
    process runs the threads it ran before the goals (none is started, or kept, per goal)."""
    robots = [f"fibo_threads_{i}" for i in range(8)]
    robot = robot_process(*robots)
    model, src = fibo_build
    configs = [
        RuntimeConfig(robot=r, bus=broker.url, property_period=0, state_dir="", mission_timeout=60.0, call_timeout=15.0)
        for r in robots
    ]
    link = connect(model, model.package_name, configs, ros=2, package_paths=[src])
    engines = []
    app = AppClient(broker.url, [f"td2adaptor/{r}/#" for r in robots])
    try:
        for r in robots:
            assert until(lambda r=r: rejects(link.ports[r]), 30, 0.1)
        engines = [serve(model, link.ports[c.robot], c) for c in configs]
        # one goal to its end first: whatever is made on first use is made now (a thread kept for the next goal too)
        app.send(topic(robots[0]), {"source": "test", "correlation": "warm", "payload": {"order": 1}})
        app.wait(terminal("feedback", "warm"), timeout=30)
        before = goal_threads()
        for r in robots:
            app.send(topic(r), {"source": "test", "correlation": f"{r}-slow", "payload": {"order": SLOW}})

        def running(r: str) -> bool:
            return any("feedback" in e["payload"] for e in feedback(app.events, f"{r}-slow"))

        app.wait(lambda _: all(running(r) for r in robots), timeout=30)
        during = goal_threads()
        for r in robots:
            app.send(topic(r, "/cancel"), {"source": "test", "correlation": f"{r}-cancel"})
        for r in robots:
            app.wait(terminal("feedback", f"{r}-slow"), timeout=30)
            assert feedback(app.events, f"{r}-slow")[-1]["payload"]["state"] == "cancelled"
        assert during == before, sorted(set(during.items()) ^ set(before.items()))
    finally:
        app.close()
        for engine in engines:
            engine.stop()
        link.close()
        robot.stop()


def test_a_goal_past_its_mission_timeout_fails_and_the_server_is_asked_to_cancel_it(
    fibo_build: tuple[Model, Path], fibo_robot: Process, broker: Mosquitto
) -> None:
    """The mission timeout is a timer of the goal's machine: the goal ends `failed`/`timeout` once it passes, with
    one terminal event, and the action server is asked to cancel it (it ends the goal canceled)."""
    edge = Edge(fibo_build, broker, ROBOT, mission_timeout=1.5)
    try:
        fibo_robot.seen.clear()
        edge.send("", {"correlation": "late", "payload": {"order": SLOW}})
        fibo_robot.wait_for(lambda e: e.get("event") == "goal" and e.get("ns") == ROBOT and e.get("order") == SLOW, 10)
        fibo_robot.seen.clear()
        events = edge.ended("late", timeout=20)
        last = events[-1]["payload"]
        assert (last["state"], last["reason"]) == ("failed", "timeout"), last
        assert "mission timeout of 1.5 s" in last["message"]
        assert sum(1 for e in events if e["payload"]["terminal"]) == 1
        assert events[0]["payload"]["result"] == "accepted" and any("feedback" in e["payload"] for e in events)
        end = fibo_robot.wait_for(lambda e: e.get("event") == "end" and e.get("ns") == ROBOT, timeout=10)
        assert end["status"] == "canceled", end
    finally:
        edge.close()
