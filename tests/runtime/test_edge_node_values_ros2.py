"""Nothing wrong reaches a robot (issue 30, items 1 and 2), end to end: an application on a real mosquitto, the
edge node on real ROS 2 Jazzy through the generated rclpy package, a real rclpy robot in its own context.

A `float64[]` field holding 1e400, a float32 one holding 3.5e38 (it would reach the robot as infinity), a
written property holding -1e400 or 3.5e38 (envelope and WoT topics alike), a valid invoke whose correlation is
a lone surrogate: each is answered with `invalid-event` naming the path, and the robot hears nothing of it;
the valid events after them are the only ones it sees (FLT_MAX reaching it as FLT_MAX).
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.model import Model
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime import PortTimeout, PortUnavailable, RuntimeConfig, serve
from td2adaptor.runtime.node.roslink import connect
from tests.ros2.common import answered
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import terminal
from tests.runtime.rclpy_robot import ServiceRobot, generate_rclpy

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOT = "values_edge"
T = f"td2adaptor/{ROBOT}"
W = f"{T}/{WOT_LEVEL}"
FLT_MAX = 3.4028234663852886e38
DEEP = "/float32_value" + "/0" * 62  # the 64th level below the event (a WoT message: its own path)


def _form(name: str, ros_type: str, op: Any) -> dict[str, Any]:
    return {
        "href": f"ros:levels/{name}",
        "op": op,
        "rosv:name": f"/{{{{robotName}}}}/levels/{name}",
        "rosv:type": ros_type,
    }


def values_td() -> dict[str, Any]:
    """Two plain actions on test_msgs services (float32/float64 scalars; float64[3] and float32[3] arrays) and
    a written std_msgs/Float32 property, latched so that the robot hears it whenever it subscribed."""
    level = _form("level", "std_msgs/msg/Float32", ["writeproperty"])
    level.update({"rosv:latch": True, "rosv:qos": {"durability": "transient_local", "depth": 1}})
    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "id": "urn:dev:wot:test:values-edge",
        "title": "Values Edge Bot",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "actions": {
            "setBasic": {
                "rosv:component": "LevelComponent",
                "forms": [_form("basic", "test_msgs/srv/BasicTypes", "invokeaction")],
            },
            "setArrays": {
                "rosv:component": "LevelComponent",
                "forms": [_form("arrays", "test_msgs/srv/Arrays", "invokeaction")],
            },
        },
        "properties": {"level": {"rosv:component": "LevelComponent", "writeOnly": True, "forms": [level]}},
    }


class LevelRobot(ServiceRobot):
    """Serves the two services and listens to the level topic; records every value that reached it."""

    def __init__(self, namespace: str) -> None:
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from std_msgs.msg import Float32
        from test_msgs.srv import Arrays, BasicTypes

        super().__init__("values_robot")
        self.heard: list[Any] = []

        def basic(request: Any, response: Any) -> Any:
            with self.lock:
                self.heard.append(("basic", request.float32_value, request.float64_value))
            return response

        def arrays(request: Any, response: Any) -> Any:
            with self.lock:
                self.heard.append(("arrays", list(request.float32_values), list(request.float64_values)))
            return response

        def level(msg: Any) -> None:
            with self.lock:
                self.heard.append(("level", msg.data))

        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.subscription = self.node.create_subscription(Float32, f"/{namespace}/levels/level", level, qos)
        services = [(BasicTypes, "levels/basic", basic), (Arrays, "levels/arrays", arrays)]
        self.serve([(t, f"/{namespace}/{n}", h) for t, n, h in services])

    def seen(self) -> list[Any]:
        with self.lock:
            return list(self.heard)

    def forget(self) -> None:
        with self.lock:
            self.heard.clear()


@pytest.fixture(scope="module")
def build(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path]:
    base = tmp_path_factory.mktemp("values-edge")
    share = Path(sys.prefix) / "share" / "test_msgs"  # the Jazzy wheel's own definitions
    assert (share / "srv" / "Arrays.srv").is_file(), share
    for kind in ("msg", "srv"):
        shutil.copytree(share / kind, base / "interfaces" / "test_msgs" / kind)
    model, src, _ = generate_rclpy(values_td(), base / "interfaces", base)
    return model, src


@pytest.fixture(scope="module")
def robot(ros2_domain: int) -> Iterator[LevelRobot]:
    r = LevelRobot(ROBOT)
    yield r
    r.stop()


def answers(port: Any) -> bool:
    """Whether the robot answers yet (`answered`)."""
    return answered(lambda: port.call("LevelComponent", "setBasic", {}, 1.0), (PortUnavailable, PortTimeout))


def test_values_no_ros_type_holds_are_refused_naming_the_path_and_never_reach_the_robot(
    build: tuple[Model, Path], robot: LevelRobot, broker: Mosquitto
) -> None:
    model, src = build
    config = RuntimeConfig(robot=ROBOT, bus=broker.url, call_timeout=15.0, property_period=0, state_dir="")
    link = connect(model, model.package_name, [config], ros=2, package_paths=[src])
    app: AppClient | None = None
    engine = None
    try:
        port = link.ports[ROBOT]
        assert until(lambda: answers(port), 30, 0.1)
        robot.forget()
        engine = serve(model, port, config)
        app = AppClient(broker.url, [f"{T}/error", f"{W}/error", f"{T}/+/+/feedback"])
        basic, arrays = f"{T}/LevelComponent/setBasic", f"{T}/LevelComponent/setArrays"
        refused = [
            (arrays, b'{"correlation":"a1","payload":{"float64_values":[1.0,1e400,2.0]}}', "/payload/float64_values/1"),
            (basic, b'{"correlation":"b1","payload":{"float32_value":3.5e38}}', "/payload/float32_value"),
            (basic, b'{"correlation":"b2","payload":{"float64_value":-1e400}}', "/payload/float64_value"),
            (f"{T}/LevelComponent/level/write", b'{"payload":{"data":-1e400}}', "/payload/data"),
            # a WoT message: the path in the message its consumer sent (it has no payload member)
            (f"{W}/LevelComponent/level", b'{"data":3.5e38}', "/data"),
            (
                f"{W}/LevelComponent/setArrays",
                b'{"correlationId":"a2","float32_values":[0,-3.5e38,0]}',
                "/float32_values/1",
            ),
            (basic, b'{"correlation":"\\ud800","payload":{"float64_value":1.5}}', "/correlation"),  # valid but for it
            (f"{W}/LevelComponent/setBasic", b'{"float32_value":' + b"[" * 100 + b"]" * 100 + b"}", DEEP),
        ]
        for topic, raw, _ in refused:
            app.send(topic, raw)
        app.wait(lambda ev: sum(1 for t, _ in ev if t == f"{T}/error") >= len(refused), timeout=30)
        errors = [e for t, e in app.events if t == f"{T}/error"]
        assert [e["payload"]["code"] for e in errors] == ["invalid-event"] * len(refused), errors
        assert sorted(e["payload"]["errors"][0]["path"] for e in errors) == sorted(p for _, _, p in refused)
        assert all("Infinity" not in e["payload"]["message"] for e in errors)
        assert sorted(e["correlation"] for e in errors if "correlation" in e) == ["a1", "a2", "b1", "b2"]
        # the WoT consumers got the same answers to their own messages (not to the envelope events)
        on_wot = [(topic, path) for topic, _, path in refused if topic.startswith(W)]
        app.wait(lambda ev: sum(1 for t, _ in ev if t == f"{W}/error") >= len(on_wot), timeout=10)
        wot = [e for t, e in app.events if t == f"{W}/error"]
        assert sorted((e["topic"], e["errors"][0]["path"]) for e in wot) == sorted(on_wot)
        # nested deeper than the JSON parser follows (the WoT adapter's RecursionError went unanswered)
        app.send(f"{W}/LevelComponent/setArrays", b"[" * 3000 + b"]" * 3000)
        app.wait(lambda ev: sum(1 for t, _ in ev if t == f"{T}/error") > len(refused), timeout=30)
        deep = [e for t, e in app.events if t == f"{T}/error"][-1]["payload"]
        assert deep["code"] == "invalid-event" and "nested more than 64 levels deep" in deep["message"]

        # what the robot can hold goes through, and is all it ever heard
        app.send(basic, {"correlation": "ok1", "payload": {"float32_value": FLT_MAX, "float64_value": 1e308}})
        app.send(arrays, {"correlation": "ok2", "payload": {"float64_values": [1.0, -1e308, 2.0]}})
        app.send(f"{T}/LevelComponent/level/write", {"payload": {"data": -FLT_MAX}})
        app.wait(terminal("feedback", "ok1"), timeout=30)
        app.wait(terminal("feedback", "ok2"), timeout=30)
        assert until(lambda: len(robot.seen()) == 3, 15)
        seen = sorted(robot.seen(), key=lambda h: h[0])
        assert seen == [
            ("arrays", [0.0, 0.0, 0.0], [1.0, -1e308, 2.0]),
            ("basic", FLT_MAX, 1e308),  # FLT_MAX as a float32, as sent
            ("level", -FLT_MAX),
        ], seen
        assert len([t for t, e in app.events if t == f"{T}/error"]) == len(refused) + 1  # none about them
    finally:
        if app is not None:
            app.close()
        if engine is not None:
            engine.stop()
        link.close()
