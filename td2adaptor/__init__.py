"""td2adaptor: W3C WoT Thing Descriptions of robots → ROS adaptor packages."""

from __future__ import annotations

__version__ = "0.1.0"
