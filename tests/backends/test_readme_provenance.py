"""The generated ROS packages' READMEs say where each interface package comes from: the standard ones with the
ROS 2 wheel or the Debian ROS 1 package that provides them, the robot's own from its interface folders."""

from __future__ import annotations

import td2adaptor
from td2adaptor.backends.registry import load
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import Model
from tests.conftest import EXAMPLE, REPO


def _readme(backend: str, model: Model) -> str:
    tree = load(backend).generate(model, GenOptions(), Diagnostics())
    [path] = [p for p in tree.files if p.count("/") == 1 and p.endswith("/README.md")]
    return tree.files[path].decode()


def test_standard_and_own_interface_packages_are_told_apart() -> None:
    std = td2adaptor.compile(REPO / "tests" / "golden" / "cases" / "std_robot" / "td.json").model
    rb1 = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[EXAMPLE / "interfaces"]).model
    assert std is not None and rb1 is not None
    assert "pip install ros-jazzy-builtin-interfaces ros-jazzy-geometry-msgs ros-jazzy-nav-msgs" in _readme(
        "rclpy", std
    )
    assert "apt install python3-geometry-msgs python3-nav-msgs python3-sensor-msgs" in _readme("rospy", std)
    assert "robot's own ones" not in _readme("rclpy", std)
    for backend in ("rclpy", "rospy"):
        text = _readme(backend, rb1)
        assert "ar_track_alvar_msgs, procedures_msgs, robot_local_control_msgs, robotnik_msgs." in text
        assert "ros-jazzy-procedures-msgs" not in text and "python3-procedures-msgs" not in text
