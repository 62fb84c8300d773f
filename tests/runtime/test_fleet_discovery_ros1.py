"""`td2adaptor run --ros 1 --discover` (issue 32) on real ROS 1 (Debian's rosmaster and rospy): the node reads
the master's graph, serves the simulated RB-1 that registers there, through a ROS 1 bridge of its own, and
retires it once it has left the master for the grace period. No mocks.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest

from tests import generated
from tests.conftest import EXAMPLE
from tests.ros1 import harness
from tests.ros1.harness import Master
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, check_mission, until
from tests.runtime.rb1 import GOAL, terminal

PKG = "robotnik_rb_1_adaptor"
ROBOT = "disc_ros1"


@pytest.fixture(scope="module")
def package_src(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    _, package = generated.generate(
        "rospy", EXAMPLE / "td.json", tmp_path_factory.mktemp("rospy"), interfaces=[EXAMPLE / "interfaces"]
    )
    assert package.name == PKG
    return package / "src"


def statuses(app: AppClient) -> list[str]:
    return [e["payload"]["state"] for t, e in list(app.events) if t == f"td2adaptor/{ROBOT}/status"]


def test_discovery_on_the_ros1_master_serves_a_robot_that_registers_and_retires_it_when_it_leaves(
    master: Master, package_src: Path, tmp_path: Path
) -> None:
    interfaces = harness.interfaces_dir()
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"], client_id="disc-ros1-app")
    environ = {**os.environ, "ROS_HOME": str(master.home), "ROS_IP": "127.0.0.1", "ROS_HOSTNAME": "127.0.0.1"}
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--ros", "1", "--package", PKG]
    args += ["--bus", broker.url, "--master-uri", master.uri, "--ros1-python", harness.SYSTEM_PYTHON]
    args += ["--package-path", str(package_src), "--package-path", str(interfaces), "--poll-period", "0.05"]
    args += ["--property-period", "0", "--discover", "--discover-grace", "1"]
    run = RunProcess(args, env=environ)
    try:
        run.wait_ready()
        with harness.run_sim(master, interfaces, ROBOT, "--duration", "0.5"):
            appeared = time.monotonic()
            assert until(lambda: statuses(app)[-1:] == ["online"], 30), run.output()
            took = time.monotonic() - appeared
            # a bridge process of its own starts for it (ROS 1 measured 1.7 s on a quiet machine): looser than ROS 2
            assert took <= 6.0, f"served {took:.2f} s after it registered"
            app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "r1", "payload": GOAL})
            app.wait(terminal("feedback", "r1"), timeout=30)
            check_mission(app.events, "r1", ["queued", "running", "finished"])
        assert until(lambda: statuses(app)[-1:] == ["offline"], 30), run.output()
        assert until(lambda: "discovery: removed disc_ros1" in run.output(), 10), run.output()
        assert run.terminate(signal.SIGTERM) == 0, run.output()
    finally:
        run.close()
        app.close()
        broker.stop()


def test_discovery_on_the_ros1_master_retires_a_robot_that_was_killed_and_stays_registered(
    master: Master, package_src: Path, tmp_path: Path
) -> None:
    """A killed ROS 1 node (SIGKILL, a crash) is never unregistered: the master lists its services for ever. The
    node finds it dead (its XML-RPC API refuses connections) and retires the robot after the grace."""
    robot = "killed_ros1"
    interfaces = harness.interfaces_dir()
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    app = AppClient(broker.url, [f"td2adaptor/{robot}/#"], client_id="disc-ros1-killed-app")
    environ = {**os.environ, "ROS_HOME": str(master.home), "ROS_IP": "127.0.0.1", "ROS_HOSTNAME": "127.0.0.1"}
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--ros", "1", "--package", PKG]
    args += ["--bus", broker.url, "--master-uri", master.uri, "--ros1-python", harness.SYSTEM_PYTHON]
    args += ["--package-path", str(package_src), "--package-path", str(interfaces)]
    args += ["--property-period", "0", "--discover", "--discover-grace", "1"]
    run = RunProcess(args, env=environ)

    def states() -> list[str]:
        return [e["payload"]["state"] for t, e in list(app.events) if t == f"td2adaptor/{robot}/status"]

    try:
        run.wait_ready()
        with harness.run_sim(master, interfaces, robot, "--duration", "0.5") as sim:
            assert until(lambda: states()[-1:] == ["online"], 30), run.output()
            sim.process.kill()
            sim.process.wait()
            killed = time.monotonic()
            assert until(lambda: states()[-1:] == ["offline"], 15), run.output()
            assert time.monotonic() - killed < 6.0  # the grace (1 s) after a look found it dead
        assert until(lambda: f"discovery: removed {robot}" in run.output(), 10), run.output()
        assert run.terminate(signal.SIGTERM) == 0, run.output()
    finally:
        run.close()
        app.close()
        broker.stop()


def test_discovery_names_the_ros1_master_it_cannot_read_and_how_to_name_another(
    package_src: Path, tmp_path: Path
) -> None:
    """Without ROS_MASTER_URI (or with a master that is not running) the node said only "the ROS graph cannot be
    read ([Errno 111] Connection refused)": not which master, nor how to give one."""
    from tests.ports import free_port

    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    nobody = f"http://127.0.0.1:{free_port()}/"
    environ = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--ros", "1", "--package", PKG]
    args += ["--bus", broker.url, "--master-uri", nobody, "--ros1-python", harness.SYSTEM_PYTHON]
    args += ["--package-path", str(package_src), "--discover"]
    run = RunProcess(args, env=environ)
    try:
        run.wait_ready()
        assert until(lambda: "cannot be read" in run.output(), 10), run.output()
        line = next(x for x in run.output().splitlines() if "cannot be read" in x)
        assert nobody in line and "--master-uri" in line and "ROS_MASTER_URI" in line, line
        assert "Errno" not in line, line
        assert run.terminate(signal.SIGTERM) == 0, run.output()
    finally:
        run.close()
        broker.stop()
