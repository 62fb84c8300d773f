"""10,000-case fuzzing of the whole pipeline (issue 6): valid binding TDs round-trip through gen, and
mutations of the RB-1 TD never end in a traceback. Usage: .venv/bin/python bench/fuzz.py [CASES]

Prints cases run, time and failures (any exception other than a diagnosed rejection counts).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from hypothesis import HealthCheck, given, settings

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.frontend.test_fuzz_frontend import mutated  # noqa: E402
from tests.fuzz.strategies import binding_tds, round_trip  # noqa: E402

EXAMPLE = REPO / "examples" / "robotnik_rb1"


def main() -> None:
    cases = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    half = cases // 2
    opts = settings(max_examples=half, deadline=None, database=None, suppress_health_check=list(HealthCheck))
    counts = {"valid": 0, "mutated": 0}

    @opts
    @given(binding_tds())
    def valid(td: dict[str, object]) -> None:
        counts["valid"] += 1
        round_trip(td)

    @opts
    @given(mutated())
    def mutations(data: bytes) -> None:
        counts["mutated"] += 1
        round_trip(json.loads(data), [EXAMPLE / "interfaces"], expect_valid=False)

    failures = 0
    for name, fn in (("valid binding TDs", valid), ("RB-1 mutations", mutations)):
        t0 = time.perf_counter()
        try:
            fn()
            status = "ok"
        except Exception as exc:  # noqa: BLE001 - report, count, go on
            failures += 1
            status = f"FAILED: {type(exc).__name__}: {str(exc)[:300]}"
        key = "valid" if fn is valid else "mutated"
        print(f"{name:<20} {counts[key]:6d} cases  {time.perf_counter() - t0:7.1f} s  {status}")
    print(f"tracebacks: {failures}")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
