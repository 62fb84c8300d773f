"""A request field named like a Python builtin or keyword, or like a parameter of the generated methods, through
the edge node on real ROS 2 Jazzy (the engine on the in-process bus).

The generated constructors give such a field a trailing `_` (`open_`, `goal_`: backends/_python/names.py), and
the edge node called them with the events' ROS names: every invoke of such an action failed `call-failed`,
"construct_makePlan_Msg() got an unexpected keyword argument 'goal'" (a new user's lift: `SetDoor.open`). Here
`nav_msgs/srv/GetPlan`, whose request has `start`, `goal` and `tolerance`, served by a real rclpy node."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.model import Model
from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.node.roslink import RosLink, connect
from tests.runtime.edge import until
from tests.runtime.rb1 import LocalApp, terminal
from tests.runtime.rclpy_robot import ServiceRobot, generate_rclpy

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOT = "planner_bot"


def planner_td() -> dict[str, Any]:
    form = {"href": "ros:make_plan", "op": "invokeaction", "rosv:name": "/{{robotName}}/make_plan"}
    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": "Planner Bot",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "actions": {
            "makePlan": {
                "rosv:component": "PlannerComponent",
                "forms": [{**form, "rosv:type": "nav_msgs/srv/GetPlan"}],
            }
        },
    }


class Planner(ServiceRobot):
    """make_plan: a path from the start to the goal (two poses), whatever the tolerance."""

    def __init__(self, namespace: str) -> None:
        from nav_msgs.srv import GetPlan

        super().__init__("planner")
        self.asked: list[tuple[float, float]] = []

        def plan(request: Any, response: Any) -> Any:
            self.asked.append((request.goal.pose.position.x, request.tolerance))
            response.plan.poses = [request.start, request.goal]
            return response

        self.serve([(GetPlan, f"/{namespace}/make_plan", plan)])


@pytest.fixture(scope="module")
def planner_build(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path]:
    import nav_msgs

    # the definitions of the ROS 2 wheels' interfaces: <prefix>/share/<package>/srv/*.srv
    share = next(p for p in Path(nav_msgs.__file__).resolve().parents if (p / "share/nav_msgs/srv").is_dir())
    model, src, _diagnostics = generate_rclpy(planner_td(), share / "share", tmp_path_factory.mktemp("planner-edge"))
    return model, src


@pytest.fixture
def robot(ros2_domain: int) -> Iterator[Planner]:
    r = Planner(ROBOT)
    yield r
    r.stop()


@pytest.fixture
def link(planner_build: tuple[Model, Path], robot: Planner) -> Iterator[RosLink]:
    model, src = planner_build
    ros = connect(model, model.package_name, [RuntimeConfig(robot=ROBOT, state_dir="")], ros=2, package_paths=[src])
    try:
        yield ros
    finally:
        ros.close()


def test_an_invoke_whose_request_has_a_field_named_like_a_generated_parameter_reaches_the_robot(
    planner_build: tuple[Model, Path], link: RosLink, robot: Planner
) -> None:
    model, src = planner_build
    assert "goal_: " in (src / model.package_name / "components.py").read_text(encoding="utf-8")  # renamed there
    broker = LocalBroker()
    config = RuntimeConfig(robot=ROBOT, call_timeout=15.0, property_period=0, state_dir="")
    engine = serve(model, link.ports[ROBOT], config, broker=broker)
    app = LocalApp(broker)
    topic = f"td2adaptor/{ROBOT}/PlannerComponent/makePlan"
    goal = {"header": {"frame_id": "map"}, "pose": {"position": {"x": 4.5, "y": -1.0}}}
    try:
        for attempt in range(10):  # a ROS 2 service may be discovered before it answers its first request
            correlation = f"p{attempt}"
            app.send(topic, {"correlation": correlation, "payload": {"goal": goal, "tolerance": 0.25}})
            app.wait(terminal("feedback", correlation), timeout=30)
            (end,) = [e for e in app.of("feedback", correlation) if e["payload"]["terminal"]]
            if end["payload"].get("reason") != "timeout":
                break
        payload = end["payload"]
        assert payload["state"] == "finished", payload
        poses = payload["output"]["plan"]["poses"]
        assert poses[1]["header"]["frame_id"] == "map" and poses[1]["pose"]["position"]["x"] == 4.5
        assert until(lambda: (4.5, 0.25) in robot.asked, 5)
    finally:
        engine.stop()
