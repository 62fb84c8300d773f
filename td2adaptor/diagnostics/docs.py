"""docs/diagnostics.md, generated from the catalogue so that the documented codes are the reported ones.

`python -m td2adaptor.diagnostics.docs` writes the file, `--check` only compares (exit 1 when stale), so CI
and a test catch a catalogue change without regenerated documentation.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from td2adaptor.diagnostics.catalogue import CATALOGUE, Entry, by_stage

DEFAULT_PATH = Path(__file__).resolve().parents[2] / "docs" / "diagnostics.md"

_HEADER = """\
# Diagnostic codes

<!-- generated from td2adaptor/diagnostics/catalogue.py by `python -m td2adaptor.diagnostics.docs`; do not edit -->

Every problem td2adaptor finds is a diagnostic: a stable code, a severity, a message, often a hint, and where
it is (`file:line:col` and a JSON pointer). Errors stop the command (exit 1); warnings and infos do not,
unless `--strict` turns every warning into an error. `td2adaptor explain CODE` prints one entry.

The hint column is general advice; a reported diagnostic usually carries a more specific hint of its own.
"""


def _cell(text: str | None) -> str:
    return (text or "").replace("|", "\\|").replace("\n", " ")


def _row(entry: Entry) -> str:
    cells = (f"`{entry.code}`", entry.severity_text(), entry.meaning, entry.hint)
    return "| " + " | ".join(_cell(c) for c in cells) + " |"


def render() -> str:
    """The whole Markdown document: one table per stage, in pipeline order."""
    parts = [_HEADER.rstrip("\n")]
    for stage, entries in by_stage():
        parts.append(f"\n## {stage.prefix}xx: {stage.title}\n\nReported by: {stage.modules}.\n")
        parts.append("| Code | Severity | Meaning | Hint |\n|---|---|---|---|")
        parts.extend(_row(e) for e in entries)
    parts.append(f"\n{len(CATALOGUE)} codes.\n")
    return "\n".join(parts)


def main(argv: Sequence[str] | None = None) -> int:
    """Write (or with `--check` compare) the documentation file; 0 when it is current afterwards."""
    parser = argparse.ArgumentParser(prog="python -m td2adaptor.diagnostics.docs", description=__doc__)
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is not current; write nothing")
    parser.add_argument("--output", type=Path, default=DEFAULT_PATH, help="default: %(default)s")
    args = parser.parse_args(argv)
    text = render()
    path: Path = args.output
    current = path.read_text(encoding="utf-8") if path.is_file() else None
    if args.check:
        if current != text:
            print(f"{path} is not current: run python -m td2adaptor.diagnostics.docs", file=sys.stderr)
            return 1
        return 0
    if current != text:
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
