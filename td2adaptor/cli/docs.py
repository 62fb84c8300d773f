"""`python -m td2adaptor.cli.docs`: writes docs/diagnostics.md, the pipeline's codes and those of every backend
td2adaptor ships; `--check` only compares (exit 1 when stale), so CI and a test catch a catalogue change
without regenerated documentation.

It lives above the backends because it documents their own codes too (the catalogue's layer knows none of
them). Plug-in backends are left out: their codes are theirs to document (`td2adaptor explain` shows them).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from td2adaptor.backends import registry
from td2adaptor.diagnostics.catalogue import STAGES, Stage
from td2adaptor.diagnostics.docs import render

DEFAULT_PATH = Path(__file__).resolve().parents[2] / "docs" / "diagnostics.md"


def documented() -> tuple[Stage, ...]:
    """The stages docs/diagnostics.md shows: the pipeline's, then each shipped backend's own."""
    return STAGES + registry.diagnostic_stages(registry.builtin())


def main(argv: Sequence[str] | None = None) -> int:
    """Write (or with `--check` compare) the documentation file; 0 when it is current afterwards."""
    parser = argparse.ArgumentParser(prog="python -m td2adaptor.cli.docs", description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is not current; write nothing")
    parser.add_argument("--output", type=Path, default=DEFAULT_PATH, help="default: %(default)s")
    args = parser.parse_args(argv)
    text = render(documented())
    path: Path = args.output
    current = path.read_text(encoding="utf-8") if path.is_file() else None
    if args.check:
        if current != text:
            print(f"{path} is not current: run python -m td2adaptor.cli.docs", file=sys.stderr)
            return 1
        return 0
    if current != text:
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
