"""Plain std_srvs services through the edge node, on real ROS 2 Jazzy (the engine on the in-process bus).

Two runtime paths of issue 12 that the other tests leave out:

* a TD action on a plain service without a procedure is a one-shot invoke: one call, then one terminal
  feedback event, `finished` with the robot's response in `output`, or `failed` (`call-failed`) when the
  robot answers `success: false`;
* a procedure whose cancel is a std_srvs/Trigger (its request cannot carry the mission id, ROS447): the
  generated `call_taskCancel` takes no `mission_id`, and GeneratedPort calls it without one (the issue's
  crash was `call_dockQuery() got an unexpected keyword argument 'mission_id'`).

The robot is a real rclpy node with its own context and executor; the adaptor is generated from the TD below
and driven through `connect` (GeneratedPort), nothing mocked.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.diagnostics import Severity
from td2adaptor.model import Model
from td2adaptor.model.events import Kind, build_catalog
from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.events import EventValidator
from td2adaptor.runtime.node.roslink import RosLink, connect
from td2adaptor.runtime.ros.genport import GeneratedPort
from tests.lowering.test_procedures import INTERFACES, STATES, procedure_td
from tests.runtime.edge import check_mission, until
from tests.runtime.rb1 import LocalApp, terminal
from tests.runtime.rclpy_robot import ServiceRobot, generate_rclpy, task_query_answers

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOT = "plain_bot"
TOPIC = f"td2adaptor/{ROBOT}"


def plain_td() -> dict[str, Any]:
    """procedure_td's task procedure with a Trigger cancel, plus two plain std_srvs actions."""
    procedure = {"missionId": "int64_value", "state": "uint8_value", "states": STATES, "message": "string_value"}
    td = procedure_td("test_msgs/srv/BasicTypes", procedure)
    # a package name of its own: another test of this worker may have imported procedure_td's task_bot_adaptor
    td["title"] = "Plain Services Bot"
    td["actions"]["taskCancel"]["forms"][0]["rosv:type"] = "std_srvs/srv/Trigger"
    for name, rtype in (("stop", "std_srvs/srv/Trigger"), ("enableMotors", "std_srvs/srv/SetBool")):
        form = {"href": f"ros:base/{name}", "op": "invokeaction", "rosv:name": f"/{{{{robotName}}}}/base/{name}"}
        td["actions"][name] = {"rosv:component": "BaseComponent", "forms": [{**form, "rosv:type": rtype}]}
    return td


class PlainRobot(ServiceRobot):
    """stop (Trigger), enableMotors (SetBool: `false` is refused, success false), and the task procedure:
    run (BasicTypes: a task of `float64_value` seconds, its id in `int64_value`), query by id, cancel (Trigger:
    cancels whatever task runs, as a robot that cannot be told which one would)."""

    def __init__(self, namespace: str) -> None:
        from std_srvs.srv import SetBool, Trigger
        from test_msgs.srv import BasicTypes

        super().__init__("plain_robot")
        self.tasks: dict[int, dict[str, Any]] = {}
        self.calls: list[str] = []

        def stop(request: Any, response: Any) -> Any:
            self.calls.append("stop")
            response.success, response.message = True, "stopped"
            return response

        def motors(request: Any, response: Any) -> Any:
            self.calls.append(f"enableMotors {request.data}")
            response.success = bool(request.data)
            response.message = "motors on" if request.data else "motors are locked"
            return response

        def run(request: Any, response: Any) -> Any:
            with self.lock:
                mid = 100 + len(self.tasks)
                self.tasks[mid] = {"start": time.monotonic(), "duration": request.float64_value, "cancelled": False}
                response.int64_value, response.uint8_value, response.string_value = mid, 0, "accepted"
            return response

        def query(request: Any, response: Any) -> Any:
            with self.lock:
                task = self.tasks.get(request.int64_value)
                response.int64_value = request.int64_value
                if task is None:
                    response.uint8_value, response.string_value = 3, f"no task {request.int64_value}"
                elif task["cancelled"]:
                    response.uint8_value, response.string_value = 4, "cancelled by the Trigger"
                elif time.monotonic() - task["start"] >= task["duration"]:
                    response.uint8_value, response.string_value = 2, "done"
                else:
                    response.uint8_value, response.string_value = 1, "working"
            return response

        def cancel(request: Any, response: Any) -> Any:
            with self.lock:
                self.calls.append("cancel")
                running = [t for t in self.tasks.values() if not t["cancelled"]]
                for task in running:
                    task["cancelled"] = True
                response.success, response.message = bool(running), f"cancelled {len(running)}"
            return response

        services = [
            (Trigger, "base/stop", stop),
            (SetBool, "base/enableMotors", motors),
            (BasicTypes, "task/run", run),
            (BasicTypes, "task/query", query),
            (Trigger, "task/cancel", cancel),
        ]
        self.serve([(t, f"/{namespace}/{n}", h) for t, n, h in services])


@pytest.fixture(scope="module")
def plain_build(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path]:
    model, src, diagnostics = generate_rclpy(plain_td(), INTERFACES, tmp_path_factory.mktemp("plain-edge"))
    assert [d.code for d in diagnostics if d.severity is Severity.WARNING] == ["ROS447"]
    return model, src


@pytest.fixture(scope="module")
def robot(ros2_domain: int) -> Iterator[PlainRobot]:
    r = PlainRobot(ROBOT)
    yield r
    r.stop()


@pytest.fixture(scope="module")
def link(plain_build: tuple[Model, Path], robot: PlainRobot) -> Iterator[RosLink]:
    model, src = plain_build
    config = RuntimeConfig(robot=ROBOT, call_timeout=15.0, state_dir="")
    ros = connect(model, model.package_name, [config], ros=2, package_paths=[src])
    # a ROS 2 service can be discovered before its server matched our response reader: the first answer may
    # be lost, so wait for one answered (side-effect free) query before relying on a call
    assert until(lambda: task_query_answers(ros.ports[ROBOT]), 30, 0.1)
    try:
        yield ros
    finally:
        ros.close()


@pytest.fixture
def app(plain_build: tuple[Model, Path], link: RosLink) -> Iterator[LocalApp]:
    model, _ = plain_build
    broker = LocalBroker()
    config = RuntimeConfig(robot=ROBOT, poll_period=0.05, call_timeout=15.0, property_period=0, state_dir="")
    engine = serve(model, link.ports[ROBOT], config, broker=broker)
    client = LocalApp(broker)
    try:
        yield client
    finally:
        engine.stop()


def test_one_shot_invoke_of_a_plain_service(app: LocalApp, robot: PlainRobot) -> None:
    app.send(f"{TOPIC}/BaseComponent/stop", {"correlation": "s1"})
    app.wait(terminal("feedback", "s1"), timeout=30)
    (event,) = app.of("feedback", "s1")  # no queued/running: one call, one terminal event
    assert event["payload"]["state"] == "finished" and event["payload"]["terminal"] is True
    assert event["payload"]["output"] == {"success": True, "message": "stopped"}
    assert robot.calls.count("stop") == 1

    app.send(f"{TOPIC}/BaseComponent/enableMotors", {"correlation": "m1", "payload": {"data": True}})
    app.wait(terminal("feedback", "m1"), timeout=30)
    (event,) = app.of("feedback", "m1")
    assert (event["payload"]["state"], event["payload"]["output"]) == (
        "finished",
        {"success": True, "message": "motors on"},
    )


def test_one_shot_invoke_the_robot_refuses_fails_with_its_words(
    plain_build: tuple[Model, Path], app: LocalApp, robot: PlainRobot, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level("WARNING", logger="td2adaptor.runtime"):
        app.send(f"{TOPIC}/BaseComponent/enableMotors", {"correlation": "m0", "payload": {"data": False}})
        app.wait(terminal("feedback", "m0"), timeout=30)
    (event,) = app.of("feedback", "m0")
    payload = event["payload"]
    assert (payload["state"], payload["reason"], payload["terminal"]) == ("failed", "call-failed", True)
    assert "motors are locked" in payload["message"]
    assert payload["output"] == {"success": False, "message": "motors are locked"}  # the robot's whole answer
    catalog = build_catalog(plain_build[0])
    assert EventValidator(catalog).errors(catalog.find(Kind.FEEDBACK, "enableMotors"), event) == []
    assert "enableMotors False" in robot.calls
    assert any("enableMotors: failed (call-failed)" in r.getMessage() for r in caplog.records)


def test_a_cancel_without_a_mission_id_is_called_without_one(link: RosLink, robot: PlainRobot) -> None:
    port = link.ports[ROBOT]
    assert isinstance(port, GeneratedPort)
    # the lowering's mission-id slots (model Procedure.slots), as the port reads them: the query's request has one
    assert ("TaskComponent", "taskQuery") in port.layout.ids and ("TaskComponent", "taskCancel") not in port.layout.ids
    started = port.start("TaskComponent", "taskRun", {"float64_value": 60.0}, 15.0)
    assert started.mission_id is not None
    # the id cannot travel: the Trigger is called as it is (a mission_id= here was the TypeError)
    answer = port.cancel("TaskComponent", "taskCancel", started.mission_id, 15.0)
    assert answer == {"success": True, "message": "cancelled 1"}
    assert port.query("TaskComponent", "taskQuery", started.mission_id, 15.0)["uint8_value"] == 4


def test_cancel_event_of_a_procedure_whose_cancel_is_a_trigger(app: LocalApp, robot: PlainRobot) -> None:
    app.send(f"{TOPIC}/TaskComponent/taskRun", {"correlation": "t1", "payload": {"float64_value": 60.0}})
    app.wait(lambda ev: any(e["payload"].get("state") == "running" for e in _fb(ev, "t1")), timeout=30)
    cancels = robot.calls.count("cancel")
    app.send(f"{TOPIC}/TaskComponent/taskCancel", {"correlation": "c1"})
    app.wait(terminal("feedback", "t1"), timeout=30)
    fb = check_mission(app.events, "t1", ["queued", "running", "cancelled"])
    assert fb[-1]["payload"]["message"] == "cancelled by the Trigger"
    assert robot.calls.count("cancel") == cancels + 1
    assert not app.of("error", "c1"), app.of("error", "c1")


def _fb(events: list[Any], correlation: str) -> list[dict[str, Any]]:
    return [e for _, e in events if e.get("type") == "feedback" and e.get("correlation") == correlation]


def test_a_plain_call_is_counted_as_a_mission_started_as_it_is_as_one_ended(app: LocalApp) -> None:
    """The metrics (`run --metrics`) counted a plain call's end in `td2adaptor_mission_duration_seconds` but not
    its start in `td2adaptor_missions_started_total`: a new user's conveyor showed 2 missions started and 4
    ended (two goals, two plain calls)."""
    from td2adaptor.runtime.node.metrics import EdgeCollector

    def counts() -> tuple[float, float]:
        started = ended = 0.0
        for family in EdgeCollector().collect():
            for sample in family.samples:
                if sample.labels.get("robot") != ROBOT:
                    continue
                if sample.name == "td2adaptor_missions_started_total":
                    started += sample.value
                elif sample.name == "td2adaptor_mission_duration_seconds_count":
                    ended += sample.value
        return started, ended

    before = counts()
    app.send(f"{TOPIC}/BaseComponent/stop", {"correlation": "counted"})
    app.wait(terminal("feedback", "counted"), timeout=30)
    assert until(lambda: counts()[1] == before[1] + 1, 10), counts()  # the end is counted once it is out
    assert counts()[0] == before[0] + 1, (before, counts())
