"""`python -m tests.golden [--refresh] [NAME...]`: compare (or rewrite) every golden file.

Without `--refresh` it lists what differs and exits 1 when anything does; with it, it rewrites generated/,
each case's expected/ and each diagnostics snapshot, then lists what it rewrote. Review `git diff` before
committing: a golden diff is a change of td2adaptor's output, to be understood, never accepted blindly.
NAME keeps only the goldens whose name contains it (`generated`, `cases/std_robot`, `diagnostics/...`).
"""

from __future__ import annotations

import argparse
import sys

from tests.golden.goldens import COMMAND, compare, goldens


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.golden", description=__doc__.split("\n\n")[1])
    parser.add_argument("--refresh", action="store_true", help="rewrite every golden that differs")
    parser.add_argument("-q", "--quiet", action="store_true", help="no unified diffs of snapshots")
    parser.add_argument("names", nargs="*", metavar="NAME", help="only goldens whose name contains NAME")
    args = parser.parse_args(argv)
    chosen = [g for g in goldens() if not args.names or any(n in g.name for n in args.names)]
    if not chosen:
        print(f"no golden matches {' '.join(args.names)}", file=sys.stderr)
        return 2
    stale = failed = 0
    for golden in chosen:
        report = compare(golden, refresh=args.refresh)
        failed += bool(report.errors)
        stale += bool(report.differences)
        verdict = (
            "ERROR" if report.errors else "current" if report.current else "REWRITTEN" if args.refresh else "STALE"
        )
        print(f"{verdict:9} {golden.name}")
        for line in report.errors + report.differences[:40]:
            print(f"    {line}")
        if len(report.differences) > 40:
            print(f"    ... and {len(report.differences) - 40} more")
        if report.diff and not args.quiet and not args.refresh:
            print("".join(f"    {line}" for line in report.diff.splitlines(keepends=True)), end="")
    print(f"{len(chosen)} goldens: {stale} {'rewritten' if args.refresh else 'stale'}, {failed} failed")
    if failed:
        print("fix the errors above (a case or snapshot that cannot be made) first", file=sys.stderr)
    elif stale and args.refresh:
        print("review `git diff` before committing: every change must be one you meant", file=sys.stderr)
    elif stale:
        print(f"if the changes are intended: run `{COMMAND}` and review git diff", file=sys.stderr)
    return 1 if failed or (stale and not args.refresh) else 0


if __name__ == "__main__":
    sys.exit(main())
