"""What a new user ran into with the fleet features (issue 32), tried on ROS 1 with a robot nobody here wrote for
(a pan-tilt camera head) and consumed by wotpy: each test reproduces one finding on real parts (mosquitto, the
dashboard, simulated robots behind edge nodes) and holds the fix. The ROS 1 findings themselves are tested
beside the features they touch (test_presence_ros1.py, test_fleet_discovery_ros1.py).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime.ros.port import PortError
from tests import generated
from tests.conftest import EXAMPLE
from tests.ros1 import harness
from tests.ros1.harness import Master
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, until
from tests.runtime.rb1 import rb1_model


def test_the_dashboard_keeps_a_robots_status_when_something_else_is_published_on_its_status_topic(
    broker: Mosquitto,
) -> None:
    """wotpy reads a property by publishing `{"action": "read"}` on the property's topic; the `presence` property's
    topic is the robot's status topic. The dashboard took that message for the robot's status: the robot lost its
    state (`{"time": null}`) until the next status."""
    from tests.dashboard.harness import dashboard, serve_robot
    from tests.dashboard.test_dashboard_browser import wait_for_robot

    robot = serve_robot(broker.url, "wotpy_read")
    app = AppClient(broker, ["td2adaptor/wotpy_read/status"], client_id="newuser-ros1-app")
    try:
        with dashboard(broker.url) as dash:
            wait_for_robot(dash.url, "wotpy_read")

            def summary() -> dict[str, Any]:
                with urllib.request.urlopen(f"{dash.url}api/fleet", timeout=5) as answer:
                    robots = json.loads(answer.read())["robots"]
                return next(r for r in robots if r["id"] == "wotpy_read")

            assert until(lambda: (summary()["status"] or {}).get("state") == "online", 20), summary()
            app.send("td2adaptor/wotpy_read/status", {"action": "read"})  # what wotpy's read_property sends
            app.send("td2adaptor/wotpy_read/status", b"not json")
            sentinel = {"type": "error", "time": "2026-11-28T00:00:00Z", "payload": {"code": "x", "message": "after"}}
            app.send("td2adaptor/wotpy_read/error", sentinel)  # sent after them: heard after them
            assert until(lambda: (summary()["lastError"] or {}).get("message") == "after", 20), summary()
            assert summary()["status"]["state"] == "online", summary()
    finally:
        app.close()
        robot.stop()


@pytest.fixture(scope="module")
def package_src(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    _, package = generated.generate(
        "rospy", EXAMPLE / "td.json", tmp_path_factory.mktemp("rospy"), interfaces=[EXAMPLE / "interfaces"]
    )
    return package / "src"


def test_a_ros1_bridge_that_died_starts_again_while_several_robots_properties_are_read(
    master: Master, package_src: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Killed once (SIGKILL, the OOM killer), the bridge of a fleet never came back: the property reads of its
    robots, sampled in parallel, restarted it at once and wrote their requests before its first line (what to
    serve), so the new child took a read for it and died ("TypeError: string indices must be integers"), again
    at every restart, and every call said so. Its death was not logged either."""
    from tests.runtime.test_edge_node_ros1 import ROBOT, rb1_bridge

    interfaces = harness.interfaces_dir()
    bridge = rb1_bridge(rb1_model(), master, interfaces, package_src, restart_period=0.0)
    bridge.start()
    failures: list[str] = []
    stop = threading.Event()

    def read() -> None:
        port = bridge.port(ROBOT)
        while not stop.is_set():
            try:
                port.read_property("AvailabilityComponent", "availability", 5.0)
            except PortError as exc:
                failures.append(str(exc))

    readers = [threading.Thread(target=read, daemon=True) for _ in range(6)]
    try:
        with harness.run_sim(master, interfaces, ROBOT, "--duration", "0.5"):
            for reader in readers:
                reader.start()
            for _ in range(3):
                pid = bridge.pid
                assert pid is not None
                os.kill(pid, signal.SIGKILL)
                gone = {None, pid}
                assert until(lambda: bridge.pid not in gone, 20), failures[-3:]  # noqa: B023 - read at once
                answered = bridge.port(ROBOT).read_property("AvailabilityComponent", "availability", 5.0)
                assert answered["robot_id"] == ROBOT
            stop.set()
            for reader in readers:
                reader.join(20)
        assert not [f for f in failures if "indices" in f or "Error:" in f], sorted(set(failures))
        deaths = [r.getMessage() for r in caplog.records if "the ROS 1 bridge exited with code -9" in r.getMessage()]
        assert len(deaths) == 3 and all("the next call starts it again" in d for d in deaths), deaths
    finally:
        stop.set()
        bridge.close()


def _children(pid: int) -> list[int]:
    out = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True)
    return [int(p) for p in out.stdout.split()]


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGKILL], ids=["ctrl-c", "kill-9"])
def test_a_run_stopped_while_its_ros1_bridge_waits_for_the_master_leaves_no_bridge_behind(
    package_src: Path, how: signal.Signals
) -> None:
    """`run --ros 1` with no master up (ROS_MASTER_URI unset: rospy waits for localhost:11311 for ever), stopped
    with Ctrl-C ("interrupted while starting") or killed: its bridge child, which ignores SIGINT/SIGTERM and
    ends when its input closes but reads nothing while rospy waits for the master, ran on for good."""
    from tests.ports import free_port

    nobody = f"http://127.0.0.1:{free_port()}/"
    environ = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
    args = [str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--ros", "1", "--robot", "no_master"]
    args += ["--master-uri", nobody, "--ros1-python", harness.SYSTEM_PYTHON, "--property-period", "0"]
    args += ["--package-path", str(package_src), "--package-path", str(harness.interfaces_dir())]
    run = RunProcess(args, env=environ)
    bridges: list[int] = []
    try:
        assert until(lambda: "Unable to register with master" in run.output(), 60), run.output()
        bridges += _children(run.proc.pid)
        assert len(bridges) == 1, bridges
        run.proc.send_signal(how)
        run.proc.wait(30)
        # Ctrl-C: the run ends it as it stops; killed: the child ends itself (its parent gone, after a grace)
        within = 2.0 if how == signal.SIGINT else 15.0
        assert until(lambda: not _running(bridges[0]), within), f"bridge {bridges[0]} runs on:\n{run.output()}"
    finally:
        for pid in [*bridges, *_children(run.proc.pid)]:
            if _running(pid):
                os.kill(pid, signal.SIGKILL)
        run.close()


def test_a_ros1_bridge_that_waits_for_a_master_that_is_not_up_says_so(package_src: Path) -> None:
    """`run --ros 1` with no master up waited its start timeout (30 s) and said only "the ROS 1 bridge did not
    answer init within 30 s" (beside rospy's own "will keep trying"): it now names the master that does not
    answer and how to name another."""
    from td2adaptor.runtime.ros.bridge import Ros1Bridge
    from td2adaptor.runtime.ros.genport import Layout
    from td2adaptor.runtime.ros.port import RosSetupError
    from tests.ports import free_port

    nobody = f"http://127.0.0.1:{free_port()}/"
    environ = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
    bridge = Ros1Bridge(
        Layout.of(rb1_model()),
        "robotnik_rb_1_adaptor",
        [("no_master", "no_master")],
        python=harness.SYSTEM_PYTHON,
        pythonpath=[harness.interfaces_dir(), package_src],
        master_uri=nobody,
        environ=environ,
        start_timeout=3.0,
    )
    try:
        with pytest.raises(RosSetupError) as failed:
            bridge.start()
    finally:
        bridge.close()
    said = str(failed.value)
    assert f"the ROS 1 master {nobody} does not answer (Connection refused)" in said, said
    assert "--master-uri, the ros_master_uri setting or ROS_MASTER_URI" in said and "init" not in said, said
