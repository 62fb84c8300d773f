"""The `td2adaptor` command line (click). `main` is the console-script entry point.

`td2adaptor check` with no argument is what a pre-commit hook runs on every commit, and nearly always the
answer is "current": that answer is given without loading click (a third of the start-up time), through
the library's `check`. Anything else — another command, an option, a stale file, a diagnostic — goes
through the click command, which says it the documented way.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from td2adaptor.cli.main import cli

__all__ = ["cli", "main"]


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point: bad input never ends in a traceback."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args == ["check"]:
        from td2adaptor.cli.quick import check_is_current

        if check_is_current():
            sys.exit(0)
    from td2adaptor.cli.main import main as full

    full(args)


def __getattr__(name: str) -> Any:
    """`cli` (the click group) loads click only when asked for."""
    if name == "cli":
        from td2adaptor.cli.main import cli

        return cli
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
