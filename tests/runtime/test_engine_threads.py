"""The threads of an edge process do not grow with its robots or its missions (issue 31).

A hundred simulated RB-1s are served by one process (`serve_fleet`, on the local bus and on a real mosquitto),
and each runs a procedure mission to one of the ends of its state machine: finished, cancelled, timed out,
unreachable (tests/runtime/threads_proc.py, in a process of its own so that nothing else runs threads there).
The process's thread count is the same with 10 robots as with 100, at every moment while the 100 missions
run, and after them (every thread of the process: on MQTT the threads that serve the connections too);
stopping every engine ends every thread it started (the MQTT connections' serving thread is the process's and
stays). Each mission has exactly one terminal event, the one its path says.

The same with a ROS action goal in flight on every robot at once: the goals are simulated (`SimActions`, one
thread for every simulated action server) but followed as the generated packages' goals are, through the
port's callback protocol (GoalListener), so the engine's side is the one real ROS goals take; no thread is
started per goal (the real-ROS 2 counterpart is in test_edge_node_actions_ros2).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from td2adaptor.runtime.bus.mqttloop import HELPERS
from td2adaptor.runtime.loop import CALL_THREADS
from tests.runtime.broker import Mosquitto

REPO = Path(__file__).resolve().parents[2]
#: the engine's threads beside the call pool: its loop, the local bus's delivery thread
FEW = 2
#: each path's terminal state and reason
ENDS = {
    "finished": ("finished", None),
    "cancelled": ("cancelled", None),
    "timeout": ("failed", "timeout"),
    "unreachable": ("failed", "unreachable"),
}


def measure(bus: str, *mode: str) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run(
        [sys.executable, "-m", "tests.runtime.threads_proc", bus, "100", *mode],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    figures: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    return figures


def check(figures: dict[str, Any]) -> None:
    before, first, served = figures["before"], figures["first"], figures["all"]
    assert first == served, (first, served, figures["names"])  # 10 robots or 100: the same threads
    network = figures["network"]  # the MQTT connections' serving thread and its helpers (none on the local bus)
    assert network <= 1 + HELPERS, figures["names"]
    assert served - before <= CALL_THREADS + FEW + network, figures["names"]
    assert figures["in_flight"] == 100  # every mission was running at once
    app = figures["app"]  # with the application's client (on the local bus: nothing more)
    assert set(figures["during"]) == {app}, sorted(set(figures["during"]))
    assert figures["after"] == app
    assert figures["stopped"] == before + network
    for robot, ends in figures["ends"].items():
        path = figures["path"][robot]
        assert len(ends) == 1, (robot, path, figures["states"][robot])
        assert (ends[0]["state"], ends[0].get("reason")) == ENDS[path], (robot, path, ends)
        assert figures["states"][robot][:2] == ["queued", "running"], (robot, figures["states"][robot])


def test_a_hundred_robots_on_the_local_bus_run_on_a_constant_number_of_threads() -> None:
    check(measure("local"))


def test_a_hundred_robots_on_mosquitto_run_on_a_constant_number_of_threads(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    try:
        check(measure(broker.url))
    finally:
        broker.stop()


#: each goal path's terminal state and reason
GOAL_ENDS = {"finished": ("finished", None), "cancelled": ("cancelled", None), "timeout": ("failed", "timeout")}


def test_a_hundred_robots_with_a_ros_action_goal_each_run_on_a_constant_number_of_threads() -> None:
    figures = measure("local", "goals")
    before, first, served = figures["before"], figures["first"], figures["all"]
    assert first == served, (first, served, figures["names"])
    assert served - before <= CALL_THREADS + FEW, figures["names"]
    assert figures["running_at_once"]  # every robot's goal was running at one moment
    assert set(figures["during"]) == {figures["app"]}, sorted(set(figures["during"]))
    assert figures["after"] == figures["app"] and figures["stopped"] == before
    for robot, ends in figures["ends"].items():
        path = figures["path"][robot]
        assert len(ends) == 1, (robot, path, figures["states"][robot])
        assert (ends[0]["state"], ends[0].get("reason")) == GOAL_ENDS[path], (robot, path, ends)
        assert figures["states"][robot][:2] == ["queued", "running"], (robot, figures["states"][robot])
