"""A ROS 2 robot killed with SIGKILL (issue 32, "presence that tells the truth"): it stays in the graph until its
DDS participant's lease ends, so how soon the edge node can say `absent` is the robot's lease. docs/fleet.md
gives a Fast DDS profile that shortens it; this test loads that very profile (read from the page) into a
simulated RB-1 in its own process, kills the simulation with SIGKILL under a real `td2adaptor run` and measures
when the robot's status says `absent` and an invoke is answered `absent` (with Fast DDS's default profile the
robot stays `present` for 20 s). Real mosquitto, real rclpy in the session's private domain."""

from __future__ import annotations

import os
import re
import signal
import sys
import time
from pathlib import Path

from tests.conftest import REPO
from tests.ros2 import env
from tests.ros2.common import EXAMPLE, PACKAGE, Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, until
from tests.runtime.rb1 import GOAL, terminal
from tests.runtime.test_presence_ros2 import status_of

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build, ...

ROBOT = "lease_ros2"  # also its namespace: no other test's simulation serves it
LEASE = 3.0  # the profile's leaseDuration, checked below


def documented_profile() -> str:
    """The robot profile docs/fleet.md gives, as the page has it."""
    page = (REPO / "docs" / "fleet.md").read_text(encoding="utf-8")
    found = re.search(r"<!-- robot-lease-profile -->\n```xml\n(.*?)```", page, re.S)
    assert found, "docs/fleet.md lost its robot lease profile"
    return found.group(1)


def test_a_robot_killed_with_a_short_lease_is_absent_within_its_lease(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, broker: Mosquitto, tmp_path: Path
) -> None:
    profile = documented_profile()
    assert f"<leaseDuration><sec>{int(LEASE)}</sec>" in profile
    robot_profile = tmp_path / "robot.xml"
    robot_profile.write_text(profile, encoding="utf-8")
    robot_env = env.child_env([rb1_prefix])
    robot_env.update(
        FASTDDS_DEFAULT_PROFILES_FILE=str(robot_profile), FASTRTPS_DEFAULT_PROFILES_FILE=str(robot_profile)
    )
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "0.5", "--namespace", ROBOT]
    sim = Process(args, robot_env)

    environ = env.child_env([rb1_prefix, adaptor_build[1]])  # the edge node keeps the tests' own profile
    environ["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), environ["PATH"]])
    environ.update(TD2ADAPTOR_PRESENCE_PERIOD="0.2", TD2ADAPTOR_STATE_DIR=str(tmp_path / "state"))
    run_args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--robot", ROBOT]
    run_args += ["--bus", broker.url, "--call-timeout", "20", "--property-period", "0", "--poll-period", "0.1"]
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
    status = status_of(app, ROBOT)
    run = RunProcess(run_args, env=environ, command=[str(adaptor_build[1] / "lib" / PACKAGE / "edge_node")])
    try:
        sim.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        run.wait_ready()
        assert until(lambda: status().get("robot") == "present", 30.0), status()

        sim.proc.send_signal(signal.SIGKILL)  # no node leaves the graph: only the lease tells
        sim.proc.wait(10)
        killed = time.monotonic()
        assert until(lambda: status().get("robot") == "absent", 3 * LEASE), status()
        gone = time.monotonic() - killed
        print(f"robot absent {gone:.2f} s after SIGKILL (lease {LEASE} s; 20 s with Fast DDS's default profile)")

        sent = time.monotonic()
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "dead", "payload": GOAL})
        app.wait(terminal("feedback", "dead"), timeout=30)
        answered = time.monotonic() - sent
        assert answered < 3.0, f"answered after {answered:.1f} s: not at once (call_timeout is 20 s)"
        codes = [
            e["payload"]["code"] for _, e in app.events if e.get("type") == "error" and e.get("correlation") == "dead"
        ]
        assert codes == ["absent"], codes
    finally:
        run.close()
        sim.stop()
        app.close()
