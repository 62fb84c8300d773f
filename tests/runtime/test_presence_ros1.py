"""Presence on real ROS 1 (Debian's rospy and rosmaster, issue 32): the edge node looks at the robot through its
master, whatever reaches the robot (here the ROS 1 bridge): the simulated RB-1 stopped is `absent` and an invoke
is answered at once; started again, it is `present`. Real mosquitto."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.bridge import Ros1Bridge
from td2adaptor.runtime.ros.genport import Layout
from tests import generated
from tests.conftest import EXAMPLE
from tests.ros1 import harness
from tests.ros1.harness import Master
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import GOAL, rb1_model, terminal

PKG = "robotnik_rb_1_adaptor"
ROBOT = "pres_ros1"


@pytest.fixture(scope="module")
def package_src(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    _, package = generated.generate(
        "rospy", EXAMPLE / "td.json", tmp_path_factory.mktemp("rospy"), interfaces=[EXAMPLE / "interfaces"]
    )
    assert package.name == PKG
    return package / "src"


class Served:
    """`robot` served through a ROS 1 bridge by an engine on `broker`, and an application watching its topics."""

    def __init__(self, master: Master, package_src: Path, broker: Mosquitto, robot: str) -> None:
        self.robot = robot
        model = rb1_model()
        self.bridge = Ros1Bridge(
            Layout.of(model),
            PKG,
            [(robot, robot)],
            python=harness.SYSTEM_PYTHON,
            pythonpath=[harness.interfaces_dir(), package_src],
            master_uri=master.uri,
            timeout=10.0,
            environ=master.env(),
        )
        self.bridge.start()
        self.app = AppClient(broker, [f"td2adaptor/{robot}/#"])
        config = RuntimeConfig(
            robot=robot,
            bus=broker.url,
            ros_master_uri=master.uri,
            poll_period=0.05,
            property_period=0,
            call_timeout=10.0,
            presence_period=0.2,
            state_dir="",
        )
        self.engine = serve(model, self.bridge.port(robot), config, distro="ros1")

    def status(self) -> dict[str, Any]:
        with self.app.cond:
            topic = f"td2adaptor/{self.robot}/status"
            found = [e["payload"] for t, e in self.app.events if t == topic and "payload" in e]
        return found[-1] if found else {}

    def answered_absent_at_once(self, correlation: str) -> None:
        """An invoke now ends at once (not after call_timeout, 10 s) with the error code `absent`."""
        sent = time.monotonic()
        topic = f"td2adaptor/{self.robot}/GoToComponent/gotoRun"
        self.app.send(topic, {"correlation": correlation, "payload": GOAL})
        self.app.wait(terminal("feedback", correlation), timeout=15)
        assert time.monotonic() - sent < 3.0
        errors = [e for _, e in self.app.events if e.get("type") == "error" and e.get("correlation") == correlation]
        assert [e["payload"]["code"] for e in errors] == ["absent"]

    def close(self) -> None:
        self.engine.stop()
        self.bridge.close()
        self.app.close()


def test_a_ros1_robot_is_absent_when_its_nodes_stop_and_present_again(
    master: Master, package_src: Path, broker: Mosquitto
) -> None:
    served = Served(master, package_src, broker, ROBOT)
    interfaces = harness.interfaces_dir()
    try:
        with harness.run_sim(master, interfaces, ROBOT, "--duration", "0.3"):
            assert until(lambda: served.status().get("robot") == "present", 20.0), served.status()
            served.app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "there", "payload": GOAL})
            served.app.wait(terminal("feedback", "there"), timeout=20)
        assert until(lambda: served.status().get("robot") == "absent", 10.0), served.status()
        assert "gotoRun" in served.status()["missing"]
        served.answered_absent_at_once("gone")
        with harness.run_sim(master, interfaces, ROBOT, "--duration", "0.3"):
            assert until(lambda: served.status().get("robot") == "present", 20.0), served.status()
    finally:
        served.close()


def test_a_ros1_robot_killed_without_unregistering_is_absent_and_an_invoke_is_answered_at_once(
    master: Master, package_src: Path, broker: Mosquitto
) -> None:
    """A ROS 1 node killed (SIGKILL, a crash) stays registered with the master, which keeps listing its services;
    the edge node finds it dead (its XML-RPC API refuses connections) rather than calling it for `call_timeout`."""
    robot = "killed_ros1"
    served = Served(master, package_src, broker, robot)
    interfaces = harness.interfaces_dir()
    try:
        with harness.run_sim(master, interfaces, robot, "--duration", "0.3") as sim:
            assert until(lambda: served.status().get("robot") == "present", 20.0), served.status()
            sim.process.kill()
            sim.process.wait()
            killed = time.monotonic()
            assert until(lambda: served.status().get("robot") == "absent", 10.0), served.status()
            assert time.monotonic() - killed < 5.0
            served.answered_absent_at_once("dead")
        with harness.run_sim(master, interfaces, robot, "--duration", "0.3"):  # the same node name, again
            assert until(lambda: served.status().get("robot") == "present", 20.0), served.status()
    finally:
        served.close()
