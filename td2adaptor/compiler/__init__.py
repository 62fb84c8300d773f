"""The compiler: drives the front end, ROS type resolution and lowering into one canonical model, and the
build from there through the backends.

`compile()` (pipeline.py) is the library's entry point; the result cache answers unchanged inputs without
recompiling, and the JSON-LD stage may run in a forked child while the rest goes on (background.py).
`build.py` compiles a target's inputs (grouped by units.py) and runs its backends: `gen` and `check`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = ["Input", "Result", "compile", "load", "validate"]

if TYPE_CHECKING:
    from td2adaptor.compiler.pipeline import Input, Result, compile, load, validate


def __getattr__(name: str) -> Any:
    """The pipeline loads on first use: `resultcache`, which the CLI needs first, is importable without it."""
    if name in __all__:
        from td2adaptor.compiler import pipeline

        return getattr(pipeline, name)
    raise AttributeError(f"module 'td2adaptor.compiler' has no attribute {name!r}")
