"""Calls through the edge node overlap where the robot can serve them together, on real ROS 2 Jazzy (issue 17).

The robot's services wait for one another (a barrier of two, or a gate the test opens): a call that is only
made after the other one finished never meets it, and its handler then answers with a failure after a long
wait, so each test fails, rather than hangs, if the edge node serialises what could overlap. Nothing is timed.
The per-component rules still hold while calls overlap: a second mission of a busy component is refused at
once, and the mission in flight ends with exactly one terminal event.

The robot is plain_services' TD (TaskComponent: a procedure; BaseComponent: stop and enableMotors), served by
a real rclpy node with a reentrant callback group and four executor threads, for two robots (namespaces); the
adaptor is generated and driven through `connect` (GeneratedPort), one engine per robot on the in-process bus.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.diagnostics import Severity
from td2adaptor.model import Model
from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.node.roslink import RosLink, connect
from tests.lowering.test_procedures import INTERFACES
from tests.runtime.edge import check_mission, until
from tests.runtime.rb1 import LocalApp, terminal
from tests.runtime.rclpy_robot import ServiceRobot, generate_rclpy, task_query_answers
from tests.runtime.test_edge_node_plain_services import plain_td

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOTS = ("overlap_bot_a", "overlap_bot_b")
#: how long a handler waits for its partner call before it answers with a failure (never reached when the
#: calls overlap; a generous bound, so that a loaded machine does not fail the test)
MEET = 60.0


class MeetingRobot(ServiceRobot):
    """Both robots' services on one node. stop and enableMotors meet at `barrier` (two calls, any robot);
    taskRun waits for `gate`; taskQuery reports a run task finished once the gate is open."""

    def __init__(self) -> None:
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.executors import MultiThreadedExecutor
        from std_srvs.srv import SetBool, Trigger
        from test_msgs.srv import BasicTypes

        super().__init__("overlap_robot")
        self.barrier = threading.Barrier(2)
        self.gate = threading.Event()
        self.calls: list[str] = []
        self.tasks = 0
        group = ReentrantCallbackGroup()

        def meet(name: str) -> Any:
            def handler(request: Any, response: Any) -> Any:
                with self.lock:
                    self.calls.append(name)
                try:
                    self.barrier.wait(MEET)
                    response.success, response.message = True, "met"
                except threading.BrokenBarrierError:
                    response.success, response.message = False, "alone: the other call never came"
                return response

            return handler

        def run(request: Any, response: Any) -> Any:
            with self.lock:
                self.calls.append("taskRun")
                self.tasks += 1
                mid = self.tasks
            opened = self.gate.wait(MEET)
            response.int64_value, response.uint8_value = mid, 0 if opened else 3
            response.string_value = "accepted" if opened else "the gate never opened"
            return response

        def query(request: Any, response: Any) -> Any:
            response.int64_value, response.uint8_value, response.string_value = request.int64_value, 2, "done"
            return response

        def cancel(request: Any, response: Any) -> Any:
            response.success, response.message = True, "nothing to cancel"
            return response

        services = [
            (Trigger, "base/stop", meet("stop")),
            (SetBool, "base/enableMotors", meet("enableMotors")),
            (BasicTypes, "task/run", run),
            (BasicTypes, "task/query", query),
            (Trigger, "task/cancel", cancel),
        ]
        self.services = [
            self.node.create_service(t, f"/{ns}/{name}", h, callback_group=group)
            for ns in ROBOTS
            for t, name, h in services
        ]
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()


@pytest.fixture(scope="module")
def build(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path]:
    td = plain_td()
    td["title"] = "Overlap Bot"  # a package of its own name (plain_services' may be imported in this worker)
    model, src, diagnostics = generate_rclpy(td, INTERFACES, tmp_path_factory.mktemp("overlap-edge"))
    assert [d.code for d in diagnostics if d.severity is Severity.WARNING] == ["ROS447"]
    return model, src


@pytest.fixture(scope="module")
def robot(ros2_domain: int) -> Iterator[MeetingRobot]:
    r = MeetingRobot()
    yield r
    r.stop()


@pytest.fixture(scope="module")
def link(build: tuple[Model, Path], robot: MeetingRobot) -> Iterator[RosLink]:
    model, src = build
    configs = [RuntimeConfig(robot=r, call_timeout=2 * MEET, state_dir="") for r in ROBOTS]
    ros = connect(model, model.package_name, configs, ros=2, package_paths=[src])
    try:
        for r in ROBOTS:  # see task_query_answers: wait for a first answered query of each robot
            assert until(lambda r=r: task_query_answers(ros.ports[r]), 30, 0.1)  # type: ignore[misc]
        yield ros
    finally:
        ros.close()


@pytest.fixture
def app(build: tuple[Model, Path], link: RosLink, robot: MeetingRobot) -> Iterator[LocalApp]:
    model, _ = build
    broker = LocalBroker()
    engines = [
        serve(
            model,
            link.ports[r],
            RuntimeConfig(robot=r, poll_period=0.05, call_timeout=2 * MEET, property_period=0, state_dir=""),
            broker=broker,
        )
        for r in ROBOTS
    ]
    robot.barrier.reset()
    robot.gate.clear()
    with robot.lock:
        robot.calls.clear()
    client = LocalApp(broker)
    try:
        yield client
    finally:
        robot.gate.set()  # a run still waiting must not outlive the test
        for engine in engines:
            engine.stop()


def met(app: LocalApp, correlation: str) -> None:
    (event,) = app.of("feedback", correlation)
    payload = event["payload"]
    assert (payload["state"], payload.get("output")) == ("finished", {"success": True, "message": "met"}), payload


def test_two_calls_of_one_component_overlap(app: LocalApp) -> None:
    a = f"td2adaptor/{ROBOTS[0]}/BaseComponent"
    app.send(f"{a}/stop", {"correlation": "s"})
    app.send(f"{a}/enableMotors", {"correlation": "m", "payload": {"data": True}})
    app.wait(lambda events: terminal("feedback", "s")(events) and terminal("feedback", "m")(events), 3 * MEET)
    met(app, "s")
    met(app, "m")


def test_calls_to_two_robots_overlap(app: LocalApp) -> None:
    for i, robot in enumerate(ROBOTS):
        app.send(f"td2adaptor/{robot}/BaseComponent/stop", {"correlation": f"s{i}"})
    app.wait(lambda events: all(terminal("feedback", f"s{i}")(events) for i in range(2)), 3 * MEET)
    met(app, "s0")
    met(app, "s1")


def test_a_mission_in_flight_keeps_its_component_busy_while_other_calls_go_on(
    app: LocalApp, robot: MeetingRobot
) -> None:
    task = f"td2adaptor/{ROBOTS[0]}/TaskComponent/taskRun"
    app.send(task, {"correlation": "t1", "payload": {"float64_value": 0.0}})
    assert until(lambda: "taskRun" in robot.calls, 30)  # the run call waits in the robot
    app.send(task, {"correlation": "t2", "payload": {"float64_value": 0.0}})
    app.wait(terminal("feedback", "t2"), 30)
    (busy,) = app.of("feedback", "t2")
    assert (busy["payload"]["state"], busy["payload"]["reason"]) == ("failed", "busy")
    # the same robot's other component, and the other robot, are served while the run is in flight
    app.send(f"td2adaptor/{ROBOTS[0]}/BaseComponent/stop", {"correlation": "s0"})
    app.send(f"td2adaptor/{ROBOTS[1]}/BaseComponent/enableMotors", {"correlation": "m1", "payload": {"data": True}})
    app.wait(lambda events: terminal("feedback", "s0")(events) and terminal("feedback", "m1")(events), 3 * MEET)
    met(app, "s0")
    met(app, "m1")
    assert not app.of("feedback", "t1") and robot.calls.count("taskRun") == 1  # still waiting at the gate
    robot.gate.set()
    events = app.wait(terminal("feedback", "t1"), 30)
    check_mission(events, "t1", ["queued", "finished"])
