"""The compiler: drives the front end, ROS type resolution and lowering into one canonical model.

`compile()` (pipeline.py) is the library's entry point; the result cache answers unchanged inputs without
recompiling, and the JSON-LD stage may run in a forked child while the rest goes on (background.py).
"""

from __future__ import annotations

from td2adaptor.compiler.pipeline import Input, Result, compile, load, validate

__all__ = ["Input", "Result", "compile", "load", "validate"]
