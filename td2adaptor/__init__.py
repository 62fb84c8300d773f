"""td2adaptor: W3C WoT Thing Descriptions of robots → ROS adaptor packages.

Library API (no click needed): `load`, `validate`, `compile`, `generate`, `check`. Heavy modules load on first use, so
`import td2adaptor` stays cheap for the CLI and for build scripts.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"
__all__ = ["__version__", "check", "compile", "generate", "load", "validate"]

if TYPE_CHECKING:
    from td2adaptor.api import check, generate
    from td2adaptor.compiler.pipeline import compile, load, validate


def __getattr__(name: str) -> Any:
    if name in ("compile", "load", "validate"):
        from td2adaptor import compiler

        return getattr(compiler, name)
    if name in ("generate", "check"):
        from td2adaptor import api

        return getattr(api, name)
    raise AttributeError(f"module 'td2adaptor' has no attribute {name!r}")
