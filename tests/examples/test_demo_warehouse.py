"""`td2adaptor demo warehouse` as a user runs it (a subprocess), on ROS 2 Jazzy from PyPI with the simulated
RB-1 (and with the simulated nav_base, whose long tasks are ROS actions): on the in-process bus, and across
processes on a real mosquitto. Three carts must end up stored.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
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


def descendants(pid: int) -> set[int]:
    """Every process started under `pid`, however deep (from /proc: the demo's simulations and edge nodes)."""
    found: set[int] = set()
    todo = [pid]
    while todo:
        parent = todo.pop()
        for task in Path(f"/proc/{parent}/task").glob("*"):
            try:
                children = {int(c) for c in (task / "children").read_text().split()}
            except (OSError, ValueError):
                continue
            todo += sorted(children - found)
            found |= children
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_sigterm_stops_the_demo_with_its_simulations_and_edge_nodes(
    ros2_domain: int, rb1_prefix: Path, broker: Mosquitto
) -> None:
    """SIGTERM to the demo alone (as a supervisor sends it, not to a process group) ends it with one line, and
    its simulations and edge node processes too: Python's default SIGTERM left them running."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "td2adaptor", "demo", "warehouse", "--duration", "5", "--bus", broker.url],
        cwd=REPO,
        env=dict(os.environ, ROS_DOMAIN_ID=str(env.private_domain_id())),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    children: set[int] = set()
    try:
        assert proc.stdout is not None
        for line in proc.stdout:  # the robots are online once the start-up line comes
            if line.strip().startswith("start-up"):
                break
        children = descendants(proc.pid)
        assert len(children) >= 4, children  # the simulations and the three edge nodes at least
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(60)
        err = proc.stderr.read() if proc.stderr is not None else ""
        deadline = time.monotonic() + 20
        while any(alive(pid) for pid in children) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = sorted(pid for pid in children if alive(pid))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
        for pid in children:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert not left, f"still running after the demo's SIGTERM: {left}"
    assert code == 1 and "stopped by SIGTERM" in err and "Traceback" not in err, err
