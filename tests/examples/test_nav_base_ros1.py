"""The nav_base example on real ROS 1: its generated rospy package against the ROS 1 simulation's actionlib servers.

Debian's rospy, rosmaster and actionlib (tests/ros1/harness.py); nav_base_msgs built with genpy, its actions
expanded into their seven messages (tests/ros1/build_actions.py); the simulation (examples/nav_base/sim/ros1.py)
serves several bases, and every test drives a base of its own. The client code runs under Debian's Python.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests import generated
from tests.examples.nav_base import EXAMPLE, INTERFACES, PACKAGE
from tests.ros1 import harness
from tests.ros1.harness import Master, Sim

SIM = EXAMPLE / "sim" / "ros1.py"
BASES = tuple(f"nav1_{i}" for i in range(6))
SPEED = 2.0


@pytest.fixture(scope="module")
def genpy(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    """genpy modules of nav_base_msgs, with the seven ROS 1 messages of each action."""
    out = tmp_path_factory.mktemp("nav-genpy") / "modules"
    built = subprocess.run(
        [harness.SYSTEM_PYTHON, str(harness.HERE / "build_actions.py"), str(INTERFACES), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert built.returncode == 0, built.stderr
    return out


@pytest.fixture(scope="module")
def package(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The rospy package of examples/nav_base/td.json; its directory."""
    _, package = generated.generate(
        "rospy", EXAMPLE / "td.json", tmp_path_factory.mktemp("nav-rospy"), interfaces=[INTERFACES]
    )
    assert package.name == PACKAGE
    return package


@pytest.fixture(scope="module")
def sim(master: Master, genpy: Path) -> Iterator[Sim]:
    args = [harness.SYSTEM_PYTHON, str(SIM), "--speed", str(SPEED), "--feedback-rate", "20", "--run-for", "600"]
    for ns in BASES:
        args += ["--namespace", ns]
    proc = subprocess.Popen(args, env=master.env(genpy), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    running = Sim(proc, [])
    try:
        running.read_until('{"event": "ready"', 30.0)
        yield running
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
        if proc.stdout is not None:
            proc.stdout.close()


def client(master: Master, genpy: Path, package: Path, base: int, body: str) -> Any:
    """Run `body` under Debian's Python with the components of base BASES[base] as nav, dock and bot, and a
    `pose(x, y)` helper; it calls emit() with what the test checks."""
    prelude = (
        f"from {PACKAGE} import *\n"
        f"kw = dict(timeout=10.0, wait_timeout=15.0)\n"
        f"nav = NavigationComponent({BASES[base]!r}, **kw)\n"
        f"dock = DockingComponent({BASES[base]!r}, **kw)\n"
        f"bot = BaseComponent({BASES[base]!r}, **kw)\n"
        "def pose(x, y):\n"
        "    p = nav.construct_navigateToPose_Goal()\n"
        "    p.pose.header.frame_id = 'map'\n"
        "    p.pose.pose.position.x, p.pose.pose.position.y, p.pose.pose.orientation.w = x, y, 1.0\n"
        "    return p\n"
    )
    return harness.run_client(master, [genpy, package / "src"], prelude + body)


@pytest.fixture(scope="module")
def run(master: Master, genpy: Path, package: Path, sim: Sim) -> Any:
    return lambda base, body: client(master, genpy, package, base, body)


def test_goal_accepted_feedback_then_result(run: Any) -> None:
    out = run(
        0,
        "goal = nav.send_navigateToPose(pose(2.0, 0.0))\n"
        "left = [fb.distance_remaining for fb in goal.feedback(timeout=10)]\n"
        "result = goal.result(timeout=10)\n"
        "emit({'id': goal.goal_id, 'left': left, 'code': result.error_code, 'msg': result.error_msg,\n"
        "      'status': goal.status, 'done': goal.done})\n",
    )
    assert out["id"] and (out["code"], out["msg"], out["status"], out["done"]) == (0, "", "succeeded", True)
    # 2 m at SPEED with feedback at 20 Hz: several messages, the distance shrinking
    left = out["left"]
    assert len(left) >= 3 and left == sorted(left, reverse=True) and left[0] > left[-1], left


def test_cancel_mid_goal(run: Any) -> None:
    out = run(
        1,
        "goal = nav.send_navigateToPose(pose(8.0, 0.0))\n"
        "first = next(goal.feedback(timeout=10))\n"
        "accepted = goal.cancel(timeout=10)\n"
        "try:\n"
        "    goal.result(timeout=10)\n"
        "    emit('succeeded?')\n"
        "except GoalCanceled as e:\n"
        "    emit({'first': first.distance_remaining, 'accepted': accepted, 'status': goal.status,\n"
        "          'reason': e.reason, 'msg': e.response.error_msg, 'is_call_failed': isinstance(e, CallFailed)})\n",
    )
    assert out["accepted"] is True and out["status"] == "canceled" and out["is_call_failed"]
    assert out["reason"] == out["msg"] == "canceled" and 0 < out["first"] <= 8.0


def test_goals_rejected_with_the_robots_reason(run: Any) -> None:
    out = run(
        2,
        "reasons = []\n"
        "try:\n"
        "    nav.send_navigateToPose(pose(50.0, 0.0))\n"
        "except GoalRejected as e:\n"
        "    reasons.append(e.reason)\n"
        "running = nav.send_navigateToPose(pose(6.0, 0.0))\n"
        "try:\n"
        "    dock.send_dockRobot(dock.construct_dockRobot_Goal(use_dock_id=True, dock_id='cart2'))\n"
        "except GoalRejected as e:\n"
        "    reasons.append(e.reason)\n"
        "running.cancel(timeout=10)\n"
        "try:\n"
        "    running.result(timeout=10)\n"
        "except GoalCanceled:\n"
        "    reasons.append(running.status)\n"
        "emit(reasons)\n",
    )
    assert out == [
        "unreachable: (50, 0) is outside the map (x -2..10, y -4..5)",
        "busy: navigate is running",
        "canceled",
    ]


def test_docking_aborted_with_the_robots_error_code_then_docked(run: Any) -> None:
    out = run(
        3,
        "goal = dock.construct_dockRobot_Goal\n"
        "try:\n"
        "    dock.send_dockRobot(goal(use_dock_id=True, dock_id='cart3')).result(timeout=10)\n"
        "except GoalAborted as e:\n"
        "    far = [e.response.error_code, e.reason, e.response.success]\n"
        "nav.send_navigateToPose(pose(1.5, 3.0)).result(timeout=10)\n"
        "handle = dock.send_dockRobot(goal(use_dock_id=True, dock_id='cart3'))\n"
        "states = [fb.state for fb in handle.feedback(timeout=10)]\n"
        "docked = handle.result(timeout=10)\n"
        "undocked = dock.send_undockRobot().result(timeout=10)\n"
        "emit({'far': far, 'states': states, 'docked': [docked.success, docked.error_msg],\n"
        "      'undocked': [undocked.success, undocked.error_msg]})\n",
    )
    assert out["far"] == [904, "cart3 not detected: it stands at (1.5, 3), the base at (0, 0)", False]
    states = out["states"]
    assert states and states[0] == 2 and states[-1] == 3 and states == sorted(states)
    assert out["docked"] == [True, "docked to cart3"]
    assert out["undocked"] == [True, "left cart3 at (1.5, 3)"]


def test_timeouts_and_services(run: Any) -> None:
    out = run(
        4,
        "goal = nav.send_navigateToPose(pose(9.0, 0.0))\n"
        "started = time.monotonic()\n"
        "try:\n"
        "    goal.result(timeout=0.3)\n"
        "except CallTimeout as e:\n"
        "    timed_out = [str(e), time.monotonic() - started < 3.0, goal.done]\n"
        "stopped = bot.call_stop()\n"
        "try:\n"
        "    goal.result(timeout=10)\n"
        "except GoalAborted as e:\n"
        "    aborted = [e.reason, e.response.error_code]\n"
        "odom = bot.get_odom_value(timeout=10)\n"
        "emit({'timed_out': timed_out, 'stopped': [stopped.success, stopped.message], 'aborted': aborted,\n"
        "      'battery': bot.get_battery_value(timeout=10).present, 'frame': odom.header.frame_id})\n",
    )
    assert out["timed_out"] == [f"no response from /{BASES[4]}/navigate_to_pose within 0.3 s", True, False]
    assert out["stopped"] == [True, "stopped: navigate canceled"]
    assert out["aborted"] == ["stopped by the stop service", 9000]
    assert out["battery"] is True and out["frame"] == "odom"


def test_server_absent(master: Master, genpy: Path, package: Path) -> None:
    out = harness.run_client(
        master,
        [genpy, package / "src"],
        f"from {PACKAGE} import *\n"
        "nav = NavigationComponent('no_such_base', timeout=1.0, wait_timeout=0.5)\n"
        "started = time.monotonic()\n"
        "try:\n"
        "    nav.send_navigateToPose()\n"
        "except ServiceUnavailable as e:\n"
        "    emit([str(e), time.monotonic() - started < 3.0])\n",
    )
    assert "no_such_base/navigate_to_pose" in out[0] and out[1] is True, json.dumps(out)


def test_generated_package_is_lint_format_and_mypy_strict_clean(package: Path) -> None:
    """With three actions whose goals, results and feedback nest geometry_msgs and durations (ROS 1 stubs)."""
    bindir = Path(sys.executable).parent
    for cmd in (
        [str(bindir / "ruff"), "check", "--no-cache", "."],
        [str(bindir / "ruff"), "format", "--check", "--no-cache", "."],
        [str(bindir / "mypy"), "--config-file", "mypy.ini", "--cache-dir", str(package.parent / ".mypy")],
    ):
        out = subprocess.run(cmd, cwd=package, capture_output=True, text=True)
        assert out.returncode == 0, f"{' '.join(cmd[:2])}:\n{out.stdout}\n{out.stderr}"
