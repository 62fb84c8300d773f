"""The rclpy backend: an ament_python ROS 2 (Jazzy) package of typed component classes, with stubs for its messages.

`generator.py` computes everything; `templates/` holds only what varies, `verbatim/` the files copied unchanged.
"""

from __future__ import annotations

from td2adaptor.backends.rclpy.generator import generate

NAME = "rclpy"
DISTRO: str | None = "ros2"
ORDER = 10

__all__ = ["DISTRO", "NAME", "ORDER", "generate"]
