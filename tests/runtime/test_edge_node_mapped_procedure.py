"""A procedure on plain services with a mapped state field, end to end: ROS 2 Jazzy and mosquitto, no mocks.

The robot serves run/query/cancel as test_msgs/srv/BasicTypes (a real rclpy node with its own context and
executor): the run answers the mission id in `int64_value` and `uint8_value` 0 (queued); the query takes the
id in `int64_value` and answers 0 queued / 1 running / 2 finished / 4 cancelled in `uint8_value` with a text
in `string_value`; a run whose `string_value` is "refuse" is answered 3 (failed). The TD maps those values
(tests.lowering.test_procedures.MAPPED); the edge node follows the mission with them.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.model import Model
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.node.roslink import connect
from tests.lowering.test_procedures import INTERFACES, MAPPED, procedure_td
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import check_mission, until
from tests.runtime.rb1 import terminal
from tests.runtime.rclpy_robot import ServiceRobot, generate_rclpy, task_query_answers

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOT = "task_robot"
RUNNING_AFTER = 0.3


class TaskRobot(ServiceRobot):
    """The BasicTypes robot (see the module docstring); a task lasts `float64_value` seconds."""

    def __init__(self, namespace: str) -> None:
        from test_msgs.srv import BasicTypes

        super().__init__("task_robot")
        self.tasks: dict[int, dict[str, Any]] = {}
        self.next_id = 41

        def state(task: dict[str, Any]) -> tuple[int, str]:
            if task["cancelled"]:
                return 4, "cancelled by request"
            age = time.monotonic() - task["start"]
            if age >= task["duration"]:
                return 2, f"{task['name']} done"
            return (1, "working") if age >= RUNNING_AFTER else (0, "waiting")

        def run(request: Any, response: Any) -> Any:
            with self.lock:
                if request.string_value == "refuse":
                    response.uint8_value, response.string_value = 3, "refused: the robot is docked"
                    return response
                self.next_id += 1
                self.tasks[self.next_id] = {
                    "name": request.string_value,
                    "start": time.monotonic(),
                    "duration": request.float64_value,
                    "cancelled": False,
                }
                response.int64_value, response.uint8_value, response.string_value = self.next_id, 0, "accepted"
            return response

        def query(request: Any, response: Any) -> Any:
            with self.lock:
                task = self.tasks.get(request.int64_value)
                response.int64_value = request.int64_value
                if task is None:
                    response.uint8_value, response.string_value = 3, f"no task {request.int64_value}"
                else:
                    response.uint8_value, response.string_value = state(task)
            return response

        def cancel(request: Any, response: Any) -> Any:
            with self.lock:
                task = self.tasks.get(request.int64_value)
                if task is not None:
                    task["cancelled"] = True
            return query(request, response)

        self.serve(
            [
                (BasicTypes, f"/{namespace}/task/{name}", handler)
                for name, handler in (("run", run), ("query", query), ("cancel", cancel))
            ]
        )


@pytest.fixture(scope="module")
def task_build(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path]:
    model, src, _ = generate_rclpy(
        procedure_td("test_msgs/srv/BasicTypes", MAPPED), INTERFACES, tmp_path_factory.mktemp("task-edge")
    )
    return model, src


@pytest.fixture(scope="module")
def task_robot(ros2_domain: int) -> Iterator[TaskRobot]:
    robot = TaskRobot(ROBOT)
    yield robot
    robot.stop()


def test_mapped_procedure_over_mqtt(
    task_build: tuple[Model, Path], task_robot: TaskRobot, broker: Mosquitto, caplog: pytest.LogCaptureFixture
) -> None:
    model, src = task_build
    config = RuntimeConfig(
        robot=ROBOT, bus=broker.url, poll_period=0.05, call_timeout=15.0, mission_timeout=60, state_dir=""
    )
    link = connect(model, model.package_name, [config], ros=2, package_paths=[src])
    port = link.ports[ROBOT]
    # a ROS 2 service can be discovered before its server matched our response reader: the first answer may be
    # lost, so wait for one answered (side-effect free) query before relying on a call
    assert until(lambda: task_query_answers(port), 30, 0.1)
    engine = serve(model, port, config)
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"])
    run = f"td2adaptor/{ROBOT}/TaskComponent/taskRun"
    try:
        app.send(run, {"correlation": "one", "payload": {"string_value": "sweep", "float64_value": 1.0}})
        app.wait(terminal("feedback", "one"), timeout=30)
        fb = check_mission(app.events, "one", ["queued", "running", "finished"])
        assert fb[0]["mission"] == 42 and fb[-1]["payload"]["message"] == "sweep done"
        assert fb[-1]["payload"]["result"] == "2"  # the robot's value, as text

        # cancel mid-mission: the robot's cancel answer (state 4) ends it, the cancel gets a state event
        app.send(run, {"correlation": "two", "payload": {"string_value": "long", "float64_value": 60.0}})
        app.wait(lambda ev: any(e["payload"].get("state") == "running" for e in _fb(ev, "two")), timeout=20)
        app.send(f"td2adaptor/{ROBOT}/TaskComponent/taskCancel", {"correlation": "c"})
        app.wait(terminal("feedback", "two"), timeout=20)
        fb = check_mission(app.events, "two", ["queued", "running", "cancelled"])
        assert fb[-1]["payload"]["message"] == "cancelled by request"
        app.wait(lambda ev: any(e.get("correlation") == "c" and e.get("type") == "state" for _, e in ev), timeout=10)
        assert task_robot.tasks[43]["cancelled"]

        # refused by the robot (its run answer maps to failed): rejected, with its words, and logged
        with caplog.at_level("WARNING", logger="td2adaptor.runtime"):
            app.send(run, {"correlation": "three", "payload": {"string_value": "refuse"}})
            app.wait(terminal("feedback", "three"), timeout=20)
        (last,) = _fb(app.events, "three")
        assert (last["payload"]["state"], last["payload"]["reason"]) == ("failed", "rejected")
        assert last["payload"]["message"] == "refused: the robot is docked"
        assert any("taskRun: rejected" in r.getMessage() for r in caplog.records)
    finally:
        app.close()
        engine.stop()
        link.close()


def _fb(events: list[Any], correlation: str) -> list[dict[str, Any]]:
    return [e for _, e in events if e.get("type") == "feedback" and e.get("correlation") == correlation]
