"""Where a robot's software gets a standard ROS interface package: the packaging rule in one place.

The lowering names it in a diagnostic, the rclpy and rospy backends in the packages they generate and
`ros2build` in its error: a service below every stage, so a backend needs no front-half package for it.
"""

from __future__ import annotations


def providers(package: str) -> tuple[str, str]:
    """What installs a standard interface package: the ROS 2 Jazzy wheel (PyPI) and Debian's ROS 1 package."""
    dashed = package.replace("_", "-")
    return f"ros-jazzy-{dashed}", f"python3-{dashed}"
