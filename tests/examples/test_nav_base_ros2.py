"""The nav_base example end to end on real ROS 2 Jazzy: its generated rclpy adaptor against its simulation.

The adaptor's ROS 2 action clients talk to the simulation's rclpy ActionServers (examples/nav_base/sim/ros2.py)
in another process, with the example's own nav_base_msgs built by the project's interface build: goal
accepted → feedback → result, cancel mid-goal, goals rejected (busy, unreachable, motors off), docking that
fails with the robot's error code, server absent, timeouts; the std_srvs services and the topics too.
Every test drives a base of its own (tests/examples/nav_base.py: BASES), so none depends on another.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tests.conftest import REPO
from tests.examples.nav_base import BASES, SPEED
from tests.ros2.common import Process, answered

pytest_plugins = ["tests.ros2.fixtures", "tests.examples.nav_base_fixtures"]  # ros2_domain; nav_* fixtures

WAIT = 15.0  # generous deadline for anything that should take well under a second


def until(predicate: Callable[[], bool], timeout: float = WAIT, period: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period)
    return predicate()


def pose(x: float, y: float, theta: float = 0.0) -> dict[str, Any]:
    """A PoseStamped as the adaptor's constructors take it (a mapping of fields)."""
    orientation = {"z": math.sin(theta / 2), "w": math.cos(theta / 2)}
    return {"header": {"frame_id": "map"}, "pose": {"position": {"x": x, "y": y}, "orientation": orientation}}


class Base:
    """The adaptor's components for one simulated base."""

    def __init__(self, adaptor: ModuleType, node: Any, robot: str) -> None:
        kw = {"timeout": 10.0, "wait_timeout": WAIT}
        self.nav = adaptor.NavigationComponent(node, robot, **kw)
        self.dock = adaptor.DockingComponent(node, robot, **kw)
        self.base = adaptor.BaseComponent(node, robot, **kw)
        self.laser = adaptor.LaserComponent(node, robot, **kw)

    def go(self, x: float, y: float, theta: float = 0.0) -> Any:
        return self.nav.send_navigateToPose(self.nav.construct_navigateToPose_Goal(pose=pose(x, y, theta)))

    def position(self) -> tuple[float, float]:
        p = self.base.get_odom_value(timeout=WAIT).pose.pose.position
        return (p.x, p.y)

    def at(self, x: float, y: float, tolerance: float = 1e-6) -> bool:
        px, py = self.position()
        return math.hypot(px - x, py - y) <= tolerance


@pytest.fixture
def make_base(nav_adaptor: ModuleType, nav_node: Any, nav_sim: Process) -> Callable[[int], Base]:
    def make(index: int) -> Base:
        """A base whose clients all exist and whose robot has answered one of them: each test's base is new, and
        a ROS 2 server may not have discovered a new client's response reader when the client sees the server
        (its first answers are then lost, seen in CI: `answered`); the readers are announced together, so
        one answered call says the others are known too."""
        b = Base(nav_adaptor, nav_node, BASES[index])
        for component in (b.nav, b.dock, b.base, b.laser):
            component.register()
        # stopping an idle base changes nothing
        assert until(lambda: answered(lambda: b.base.call_stop(timeout=2.0), nav_adaptor.CallTimeout), WAIT)
        return b

    return make


def test_goal_accepted_feedback_then_result(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(0)
    handle = b.go(2.0, 0.0, math.pi / 2)
    assert isinstance(handle, nav_adaptor.GoalHandle) and len(handle.goal_id) == 32
    feedback = list(handle.feedback(timeout=WAIT))
    result = handle.result(timeout=WAIT)
    assert result.error_code == result.NONE == 0 and result.error_msg == ""
    assert handle.status == "succeeded"
    # driving 2 m at SPEED with feedback at 20 Hz: several messages, the distance shrinking, the pose advancing
    assert len(feedback) >= 3, len(feedback)
    remaining = [f.distance_remaining for f in feedback]
    assert remaining == sorted(remaining, reverse=True) and remaining[0] > remaining[-1]
    assert all(0.0 <= f.current_pose.pose.position.x <= 2.0 + 1e-6 for f in feedback)
    assert all(f.current_pose.header.frame_id == "map" for f in feedback)
    times = [f.navigation_time.sec + f.navigation_time.nanosec * 1e-9 for f in feedback]
    assert times == sorted(times) and times[-1] <= 2.0 / SPEED + 1e-6
    # the base is there (odometry is published on a timer: wait for a message that shows it)
    assert until(lambda: b.at(2.0, 0.0)), b.position()
    odom = b.base.get_odom_value()
    assert abs(odom.pose.pose.orientation.z - math.sin(math.pi / 4)) < 1e-6


def test_cancel_mid_goal_stops_the_base_short(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(1)
    handle = b.go(8.0, 0.0)
    first = next(iter(handle.feedback(timeout=WAIT)))
    assert first.distance_remaining > 0
    assert handle.cancel(timeout=WAIT) is True
    with pytest.raises(nav_adaptor.GoalCanceled) as caught:
        handle.result(timeout=WAIT)
    assert isinstance(caught.value, nav_adaptor.CallFailed)
    assert caught.value.response.error_msg == "canceled"
    assert handle.status == "canceled" and handle.cancel(timeout=WAIT) is False
    # it stopped on the way and stays there; the next goal is accepted again
    assert until(lambda: 0.0 < b.position()[0] < 8.0 and b.base.get_odom_value().twist.twist.linear.x == 0.0)
    stopped = b.position()
    assert b.go(*stopped).result(timeout=WAIT).error_code == 0


def test_goals_rejected_when_busy_or_unreachable(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(2)
    with pytest.raises(nav_adaptor.GoalRejected, match="rejected"):
        b.go(50.0, 0.0)  # outside the map
    running = b.go(6.0, 0.0)
    with pytest.raises(nav_adaptor.GoalRejected):
        b.go(1.0, 1.0)  # another navigation runs
    with pytest.raises(nav_adaptor.GoalRejected):
        b.dock.send_dockRobot(b.dock.construct_dockRobot_Goal(use_dock_id=True, dock_id="cart2"))  # busy too
    assert running.status in ("accepted", "executing")
    assert running.cancel(timeout=WAIT)
    with pytest.raises(nav_adaptor.GoalCanceled):
        running.result(timeout=WAIT)


def test_services_stop_and_motors(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(3)
    idle = b.base.call_stop()
    assert idle.success and idle.message == "stopped: nothing was running"
    running = b.go(8.0, 0.0)
    next(iter(running.feedback(timeout=WAIT)))
    stopped = b.base.call_stop()
    assert stopped.success and stopped.message == "stopped: navigate canceled"
    # stopped by the robot itself, not by the client's cancel: the goal ends aborted, in the robot's words
    with pytest.raises(nav_adaptor.GoalAborted) as caught:
        running.result(timeout=WAIT)
    assert caught.value.response.error_code == caught.value.response.UNKNOWN
    assert caught.value.response.error_msg == "stopped by the stop service"
    off = b.base.call_enableMotors(b.base.construct_enableMotors_Msg(data=False))
    assert off.success and off.message == "motors off"
    with pytest.raises(nav_adaptor.GoalRejected):
        b.go(1.0, 0.0)
    assert b.base.call_enableMotors(b.base.construct_enableMotors_Msg(data=True)).message == "motors on"
    assert b.go(1.0, 0.0).result(timeout=WAIT).error_code == 0


def test_dock_under_a_cart_and_undock(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(4)
    dock, goal = b.dock, b.dock.construct_dockRobot_Goal
    # not at the cart: the docking server aborts with FAILED_TO_DETECT_DOCK and says why
    far = dock.send_dockRobot(goal(use_dock_id=True, dock_id="cart3"))
    with pytest.raises(nav_adaptor.GoalAborted) as caught:
        far.result(timeout=WAIT)
    assert caught.value.response.error_code == caught.value.response.FAILED_TO_DETECT_DOCK == 904
    assert "cart3 not detected" in caught.value.response.error_msg and not caught.value.response.success
    with pytest.raises(nav_adaptor.GoalAborted) as caught:
        dock.send_dockRobot(goal(use_dock_id=True, dock_id="cart99")).result(timeout=WAIT)
    assert caught.value.response.error_code == caught.value.response.DOCK_NOT_IN_DB
    # at the cart: feedback states go INITIAL_PERCEPTION then CONTROLLING, and the base carries it away
    assert b.go(1.5, 3.0).result(timeout=WAIT).error_code == 0
    handle = dock.send_dockRobot(goal(use_dock_id=False, dock_pose=pose(1.5, 3.0)))
    states = [f.state for f in handle.feedback(timeout=WAIT)]
    result = handle.result(timeout=WAIT)
    assert result.success and result.error_code == 0 and result.error_msg == "docked to cart3"
    assert states and states[0] == 2 and states[-1] == 3 and states == sorted(states)
    assert b.go(3.0, 0.0).result(timeout=WAIT).error_code == 0
    undock = dock.send_undockRobot().result(timeout=WAIT)
    assert undock.success and undock.error_msg == "left cart3 at (3, 0)"
    with pytest.raises(nav_adaptor.GoalAborted) as caught:
        dock.send_undockRobot().result(timeout=WAIT)  # nothing docked any more
    assert caught.value.response.error_msg == "not docked"


def test_timeouts_never_block_forever(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(5)
    handle = b.go(9.0, 0.0)  # 4.5 s
    started = time.monotonic()
    with pytest.raises(nav_adaptor.CallTimeout):
        handle.result(timeout=0.3)
    assert time.monotonic() - started < 3.0
    assert not handle.done  # the goal goes on
    assert handle.cancel(timeout=WAIT)
    with pytest.raises(nav_adaptor.GoalCanceled):
        handle.result(timeout=WAIT)


def test_action_server_absent(nav_adaptor: ModuleType, nav_node: Any) -> None:
    lonely = nav_adaptor.NavigationComponent(nav_node, "no_such_base", timeout=1.0, wait_timeout=0.5)
    started = time.monotonic()
    with pytest.raises(nav_adaptor.ServiceUnavailable, match="no_such_base/navigate_to_pose"):
        lonely.send_navigateToPose()
    assert time.monotonic() - started < 3.0


def test_topics_cmd_vel_odom_battery_scan(nav_adaptor: ModuleType, make_base: Callable[[int], Base]) -> None:
    b = make_base(6)
    battery = b.base.get_battery_value(timeout=WAIT)
    assert battery.present and 0.0 < battery.percentage <= 1.0
    scan = b.laser.get_scan_value(timeout=WAIT)  # best effort, as the TD says
    assert len(scan.ranges) == 181 and all(0.0 < r <= scan.range_max for r in scan.ranges)
    # the base stands at the origin facing +x: the wall straight ahead is at x = 10
    assert abs(scan.ranges[90] - 10.0) < 1e-3
    # a held velocity command drives it forward
    assert b.at(0.0, 0.0)
    twist = b.base.construct_cmdVel_Msg(linear={"x": 0.5})

    def driven() -> bool:
        b.base.publish_cmdVel_Msg(twist)
        return b.position()[0] > 0.05

    assert until(driven)


def test_the_readme_simulator_command_works_as_written(nav_prefix: Path) -> None:
    # examples/nav_base/README.md: `.venv/bin/python -m examples.nav_base.sim.ros2 --namespace nav_base_a` (no
    # prefix: the simulation finds the checkout's build of nav_base_msgs itself, as nav_prefix made it)
    out = subprocess.run(
        [sys.executable, "-m", "examples.nav_base.sim.ros2", "--namespace", "nav_base_a", "--run-for", "1"],
        cwd=REPO,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
    assert '"event": "ready"' in out.stdout


def test_generated_package_and_user_code_pass_mypy_strict(nav_adaptor: ModuleType, tmp_path: Path) -> None:
    """The package's own check (setup.cfg: strict, with the stubs of nav_base_msgs' actions) and user code: good
    use of goals, feedback and results passes, misuse is caught."""
    import shutil

    pkg = Path(nav_adaptor.__file__ or "").parents[1]
    copy = tmp_path / pkg.name
    shutil.copytree(pkg, copy)
    (copy / "use_ok.py").write_text(
        "from rclpy.node import Node\n"
        "from nav_base_adaptor import DockingComponent, GoalAborted, NavigationComponent\n\n\n"
        "def run(node: Node) -> float:\n"
        "    nav = NavigationComponent(node, 'nav_base_a', timeout=2.0)\n"
        "    goal = nav.construct_navigateToPose_Goal(pose={'pose': {'position': {'x': 1.0}}})\n"
        "    handle = nav.send_navigateToPose(goal)\n"
        "    left = [fb.distance_remaining + fb.navigation_time.sec for fb in handle.feedback(timeout=1.0)]\n"
        "    code: int = handle.result(timeout=3.0).error_code\n"
        "    dock = DockingComponent(node, 'nav_base_a')\n"
        "    try:\n"
        "        dock.send_dockRobot(dock.construct_dockRobot_Goal(use_dock_id=True, dock_id='c')).result()\n"
        "    except GoalAborted as exc:\n"
        "        print(exc.response.error_msg, exc.response.error_code + 1)\n"
        "    return sum(left) + code\n",
        encoding="utf-8",
    )
    (copy / "use_bad.py").write_text(
        "from rclpy.node import Node\n"
        "from nav_base_adaptor import DockingComponent, NavigationComponent\n\n\n"
        "def run(node: Node) -> str:\n"
        "    NavigationComponent(node).construct_navigateToPose_Goal(behavior_tree=3)\n"
        "    dock = DockingComponent(node)\n"
        "    dock.send_dockRobot(dock.construct_undockRobot_Goal())\n"
        "    return dock.send_undockRobot().result().error_code\n",
        encoding="utf-8",
    )
    mypy = [str(Path(sys.executable).parent / "mypy"), "--cache-dir", str(tmp_path / "mypy-cache")]
    proc = subprocess.run(mypy, cwd=copy, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = subprocess.run([*mypy, "use_ok.py", "use_bad.py"], cwd=copy, capture_output=True, text=True)
    lines = [line for line in proc.stdout.splitlines() if ": error:" in line]
    assert all(line.startswith("use_bad.py") for line in lines), proc.stdout
    assert len(lines) == 3, proc.stdout
