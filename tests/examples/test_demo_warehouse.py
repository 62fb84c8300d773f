"""`td2adaptor demo warehouse` as a user runs it (a subprocess), on ROS 2 Jazzy from PyPI with the simulated
RB-1 (and with the simulated nav_base, whose long tasks are ROS actions): on the in-process bus, and across
processes on a real mosquitto. Three carts must end up stored.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.ros2 import env
from tests.runtime.broker import Mosquitto

# ros2_domain (private domain id), rb1_prefix and nav_prefix (built interfaces)
pytest_plugins = ["tests.ros2.fixtures", "tests.examples.nav_base_fixtures"]


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    b = Mosquitto(tmp_path / "broker")
    b.start()
    yield b
    b.stop()


def demo(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "td2adaptor", "demo", "warehouse", "--duration", "0.2", *args],
        cwd=REPO,
        # localhost discovery as in this worker, but a domain of its own: the simulated RB-1 the other ROS 2 tests
        # of this worker may have left running serves robots of the same names
        env=dict(os.environ, ROS_DOMAIN_ID=str(env.private_domain_id())),
        capture_output=True,
        text=True,
        timeout=90,
    )


def check_summary(out: subprocess.CompletedProcess[str], bus: str) -> None:
    assert out.returncode == 0, out.stdout + out.stderr
    lines = out.stdout.splitlines()
    assert "carts moved: 3/3" in lines, out.stdout
    assert f"bus {bus}" in lines[0]
    for cart, zone in (("cart2", "A"), ("cart3", "B"), ("cart4", "C")):
        assert re.search(rf"{cart} \(marker \d\): rb1_base_[abc] .* storage {zone} .* moved in", out.stdout), cart
    per_action = next(line for line in lines if line.startswith("bus messages per action: "))
    # one invoke and one feedback event per state change (queued, running, finished: a loaded machine may poll
    # too late to see `running`) per mission: no polling over the bus
    for action, count in (("gotoRun", 9), ("pickRun", 3), ("placeRun", 3)):
        found = re.search(rf"{action} \d\.\d \(x{count}: {count} sent, (\d+) received\)", per_action)
        assert found and 2 * count <= int(found[1]) <= 3 * count, per_action
    assert "door open" in per_action and "poseMarker check" in per_action
    assert re.search(r"^total time: \d+\.\d s \(start-up", out.stdout, re.MULTILINE)


def test_demo_warehouse_on_the_local_bus(ros2_domain: int, rb1_prefix: Path) -> None:
    check_summary(demo(), "local")


def test_demo_warehouse_across_processes_over_mqtt(ros2_domain: int, rb1_prefix: Path, broker: Mosquitto) -> None:
    check_summary(demo("--bus", broker.url), broker.url)


def test_the_readme_simulator_command_works_as_written(ros2_domain: int, rb1_prefix: Path) -> None:
    # README: `.venv/bin/python -m examples.robotnik_rb1.sim.ros2 --namespace rb1_base_a` (no prefix given: the
    # simulation finds the checkout's build of the RB-1 interfaces itself, as rb1_prefix made it)
    out = subprocess.run(
        [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--namespace", "rb1_base_a", "--run-for", "1"],
        cwd=REPO,
        env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
    assert '"event": "ready"' in out.stdout


def check_nav_base_summary(out: subprocess.CompletedProcess[str], bus: str) -> None:
    assert out.returncode == 0, out.stdout + out.stderr
    lines = out.stdout.splitlines()
    assert "carts moved: 3/3" in lines, out.stdout
    assert "nav_base robot(s)" in lines[0] and f"bus {bus}" in lines[0], lines[0]
    for cart, zone in (("cart2", "A"), ("cart3", "B"), ("cart4", "C")):
        assert re.search(rf"{cart} \(marker \d\): nav_base_[abc] .* storage {zone} .* moved in", out.stdout), cart
    per_action = next(line for line in lines if line.startswith("bus messages per action: "))
    # per goal: `queued` (accepted), one event per ROS feedback message, one terminal event; UndockRobot has
    # no feedback, so exactly two each
    for action, count in (("navigateToPose", 9), ("dockRobot", 3), ("undockRobot", 3)):
        found = re.search(rf"{action} \d+\.\d \(x{count}: {count} sent, (\d+) received\)", per_action)
        assert found and 2 * count <= int(found[1]), per_action
        if action == "undockRobot":
            assert int(found[1]) == 2 * count, per_action
    assert "door open" in per_action and "poseMarker" not in per_action


def test_demo_warehouse_with_nav_base_robots(ros2_domain: int, nav_prefix: Path) -> None:
    check_nav_base_summary(demo("--robot-kind", "nav_base"), "local")


def test_demo_warehouse_with_nav_base_robots_over_mqtt(ros2_domain: int, nav_prefix: Path, broker: Mosquitto) -> None:
    check_nav_base_summary(demo("--robot-kind", "nav_base", "--bus", broker.url), broker.url)


def test_an_unknown_robot_kind_is_a_usage_error() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "demo", "warehouse", "--robot-kind", "tugbot"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    assert "'tugbot' is not one of 'rb1', 'nav_base'" in out.stderr, out.stderr
