"""The mros backend: an mROS 1 (embedded ROS 1, C++98) application for Cortex-A9 boards.

`generator.py` computes everything; `templates/` holds only what varies, `verbatim/` the files copied unchanged;
`diagnostics.py` declares the backend's own codes (imported first: the generator reports them).
"""

from __future__ import annotations

from td2adaptor.backends.mros.diagnostics import DIAGNOSTICS
from td2adaptor.backends.mros.generator import generate

NAME = "mros"
DISTRO: str | None = "ros1"
ORDER = 30

__all__ = ["DIAGNOSTICS", "DISTRO", "NAME", "ORDER", "generate"]
