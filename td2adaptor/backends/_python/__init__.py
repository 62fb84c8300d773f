"""What the two Python backends (rclpy, rospy) share: docstrings, import blocks, reserved names, stub classes.

Not a backend (the registry skips packages whose name starts with `_`). Both generators build their view
models with these helpers, so the two generated packages wrap, sort and reserve names the same way.
"""

from __future__ import annotations

from td2adaptor.backends._python.imports import import_block, import_line, member_key
from td2adaptor.backends._python.names import METHOD_NAMES, defined_names, param_name, reserved_names
from td2adaptor.backends._python.runtime import (
    SHARED,
    common_names,
    constant,
    error_classes,
    goals_names,
    shared_source,
)
from td2adaptor.backends._python.stubs import StubClass, StubField, StubModule
from td2adaptor.backends._python.text import LINE, call_lines, docstring, wrap

__all__ = [
    "METHOD_NAMES",
    "LINE",
    "SHARED",
    "StubClass",
    "StubField",
    "StubModule",
    "common_names",
    "constant",
    "defined_names",
    "param_name",
    "call_lines",
    "docstring",
    "error_classes",
    "goals_names",
    "import_block",
    "import_line",
    "member_key",
    "reserved_names",
    "shared_source",
    "wrap",
]
