"""Workflow benchmarks (issue 6), each against a baseline measured in the same run.

* `td2adaptor check` on the RB-1 example with nothing stale, cold CLI (issue 6: <= 0.25 s; issue 17: the
  pre-commit no-op check <= 150 ms; floor python -c pass);
* `td2adaptor gen` of a 1,000-affordance TD, cold CLI, all backends (target <= 1 s), first run and re-run.

The CLI runs as `python -m td2adaptor` with this checkout first on sys.path (PYTHONPATH), so a git worktree
measures its own code (the console script imports wherever the package was installed from).
"""

from __future__ import annotations

import json
import os
import shutil
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
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
ENV["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])


def timed(cmd: list[str], cwd: Path, runs: int = 5, env: dict[str, str] | None = None) -> tuple[float, int]:
    rc = subprocess.run(cmd, cwd=cwd, capture_output=True, env=env or ENV, check=False).returncode
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=cwd, capture_output=True, env=env or ENV, check=False)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), rc


def main() -> None:
    floor, _ = timed([PY, "-c", "pass"], REPO, runs=15)
    check, rc = timed([*CLI, "check"], REPO, runs=15)
    print(
        f"td2adaptor check, RB-1, nothing stale   {check * 1000:8.1f} ms  (exit {rc})   python -c pass "
        f"{floor * 1000:6.1f} ms   ratio {check / floor:5.1f}   target <= 250 ms (issue 6), <= 150 ms (issue 17)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "synth.json").write_text(json.dumps(synthetic_td(1000)))
        cmd = [*CLI, "gen", "synth.json", "-o", "out", "--partial"]
        # a TD never seen before, on a machine that has run td2adaptor (its tool caches are warm)
        subprocess.run([*CLI, "validate", str(REPO / "examples/robotnik_rb1/td.json")], capture_output=True, env=ENV)
        new_td, rc = timed([*cmd, "--no-cache"], work, runs=3)
        files = sum(1 for p in (work / "out").rglob("*") if p.is_file()) if (work / "out").is_dir() else 0
        # the same, into an empty output directory: every file is created
        fresh = []
        for _ in range(3):
            shutil.rmtree(work / "out", ignore_errors=True)
            t0 = time.perf_counter()
            subprocess.run([*cmd, "--no-cache"], cwd=work, capture_output=True, env=ENV, check=False)
            fresh.append(time.perf_counter() - t0)
        shutil.rmtree(work / "out", ignore_errors=True)
        # the very first run of td2adaptor on a machine: empty cache directory
        empty = {**ENV, "TD2ADAPTOR_CACHE_DIR": str(work / "cache")}
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=work, capture_output=True, env=empty, check=False)
        first = time.perf_counter() - t0
        again, _ = timed(cmd, work, runs=3, env=empty)
        print(f"td2adaptor gen, 1,000 affordances, all backends ({files} files, exit {rc}):")
        print(f"  new TD (no result cache), output unchanged   {new_td * 1000:8.1f} ms   target <= 1000 ms")
        empty_out = statistics.median(fresh)
        print(f"  new TD, empty output directory               {empty_out * 1000:8.1f} ms   target <= 1000 ms")
        print(f"  re-run, nothing changed                      {again * 1000:8.1f} ms   target <= 1000 ms")
        print(f"  first run on a machine (all caches empty)    {first * 1000:8.1f} ms")


if __name__ == "__main__":
    main()
