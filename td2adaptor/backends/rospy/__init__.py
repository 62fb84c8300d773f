"""The rospy backend: a catkin ROS 1 package of typed component classes, with stubs for its messages.

`generator.py` computes everything; `templates/` holds only what varies, `verbatim/` the files copied unchanged.
"""

from __future__ import annotations

from td2adaptor.backends.rospy.generator import generate

NAME = "rospy"
DISTRO: str | None = "ros1"
ORDER = 20

__all__ = ["DISTRO", "NAME", "ORDER", "generate"]
