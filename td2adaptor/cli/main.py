"""The `td2adaptor` command line: the click group with every command registered, and the console entry point.

Commands live by stage: frontend.py (validate, types, instantiate, migrate, explain), generate.py (gen, check),
runtime.py (run, demo), fleet.py (fleet status), dashboard.py (dashboard); common.py holds the group and what
they share.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import click

from td2adaptor.cli import dashboard, fleet, frontend, generate, runtime, scaffold  # noqa: F401 - registers the commands
from td2adaptor.cli.common import EXIT_INTERNAL, cli

__all__ = ["cli", "main"]


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point: bad input never ends in a traceback."""
    try:
        cli.main(args=list(argv) if argv is not None else None, prog_name="td2adaptor", standalone_mode=True)
    except SystemExit:
        raise
    except KeyboardInterrupt:
        click.echo("td2adaptor: interrupted", err=True)
        sys.exit(130)
    except Exception as exc:  # noqa: BLE001 - the one place that turns bugs into a clean exit 3
        click.echo(f"td2adaptor: internal error: {type(exc).__name__}: {exc} (please report this)", err=True)
        sys.exit(EXIT_INTERNAL)


if __name__ == "__main__":
    main()
