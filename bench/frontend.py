"""Front-end benchmarks (issue 2). Every figure is a ratio against a baseline measured in this run.

* `td2adaptor validate` of the RB-1 TD, cold CLI process, vs `python -c pass` (issue 2: <= 0.2 s absolute;
  issue 17: <= 150 ms with the result cache);
* compile of synthetic TDs with 1,000 and 10,000 affordances, in process (issue 2: <= 1 s, linear growth;
  issue 17: 10,000 in <= 3 s);
* `td2adaptor --version` vs `python -c "import click"` (target <= 2x).

The CLI runs as `python -m td2adaptor` with this checkout first on sys.path (PYTHONPATH), so a git worktree
measures its own code (the console script imports wherever the package was installed from).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from synth import synthetic_td  # noqa: E402

PY = sys.executable
CLI = [PY, "-m", "td2adaptor"]
EXAMPLE = REPO / "examples" / "robotnik_rb1"
RUNS = {1000: 5, 10000: 3}  # in-process compiles of each synthetic TD, reported as their median


# byte-code caching as on a normal machine (this workplace sets PYTHONDONTWRITEBYTECODE)
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
ENV["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])


def cold(cmd: list[str], runs: int = 7, env: dict[str, str] | None = None) -> float:
    """Median wall time of a fresh process (after one warm-up run for the file and result caches)."""
    subprocess.run(cmd, capture_output=True, check=False, env=env or ENV)
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, capture_output=True, check=False, env=env or ENV)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def row(name: str, value: float, baseline_name: str, baseline: float, target: str) -> None:
    print(
        f"{name:<48} {value * 1000:8.1f} ms   {baseline_name:<28} {baseline * 1000:8.1f} ms"
        f"   ratio {value / baseline:5.2f}   target {target}"
    )


def main() -> None:
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}")
    base_pass = cold([PY, "-c", "pass"])
    base_click = cold([PY, "-c", "import click"])
    version = cold([*CLI, "--version"])
    row("td2adaptor --version", version, "python -c 'import click'", base_click, "<= 2x")
    cmd = [*CLI, "validate", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces")]
    row(
        "validate RB-1, cold CLI, no result cache", cold([*cmd, "--no-cache"]), "python -c pass", base_pass, "<= 200 ms"
    )
    row(
        "validate RB-1, cold CLI, result cache hit",
        cold(cmd, runs=15),
        "python -c pass",
        base_pass,
        "<= 150 ms (issue 17)",
    )

    from td2adaptor import compile as td_compile

    td_compile(str(EXAMPLE / "td.json"), interfaces=[EXAMPLE / "interfaces"])  # warm caches once
    with tempfile.TemporaryDirectory() as tmp:
        results = {}
        for n in (1000, 10000):
            path = Path(tmp) / f"synth{n}.json"
            path.write_text(json.dumps(synthetic_td(n)))
            times = []
            for _ in range(RUNS[n]):
                t0 = time.perf_counter()
                res = td_compile(str(path))
                times.append(time.perf_counter() - t0)
                assert res.model is not None, [d.message for d in res.diagnostics][:5]
            results[n] = statistics.median(times)
        row(f"compile 1,000 affordances (median of {RUNS[1000]})", results[1000], "(absolute)", 1.0, "<= 1 s")
        row(
            f"compile 10,000 affordances (median of {RUNS[10000]})",
            results[10000],
            "compile 1,000 affordances",
            results[1000],
            "linear: ~10x; <= 3 s (issue 17)",
        )


if __name__ == "__main__":
    main()
