"""A new user's first `validate`, and `gen` as the TD grows (issue 34). Figures are set against baselines
measured in the same run, in turns (A B A B ...), so that a machine whose speed drifts moves both alike:

* `td2adaptor validate` of the RB-1 TD in a fresh process without the result cache, vs `python -c pass`
  (target: <= 200 ms); once with `--no-cache` (the tool caches warm, as the other benches measure it) and
  once with `TD2ADAPTOR_NO_CACHE=1` (no cache at all: the very first run on a machine);
* `td2adaptor gen` of all backends into an empty output directory, fresh process, without the result cache:
  a 10,000-affordance TD vs a 1,000-affordance one (target: linear, <= 10.5x for 10x the affordances).

The machine's load average is printed with the figures: on a loaded machine read the ratios, not the
milliseconds. The CLI runs as `python -m td2adaptor` with this checkout first on sys.path (PYTHONPATH).

`python bench/startup_scale.py [--runs N] [--gen-runs N]`
"""

from __future__ import annotations

import argparse
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
EXAMPLE = REPO / "examples" / "robotnik_rb1"
# byte-code caching as on a normal machine (this workplace sets PYTHONDONTWRITEBYTECODE)
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
ENV["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])])


def wall(cmd: list[str], *, env: dict[str, str] = ENV, cwd: Path = REPO, before: Path | None = None) -> float:
    """Seconds from start to exit of `cmd` (after emptying `before`, not timed)."""
    if before is not None:
        shutil.rmtree(before, ignore_errors=True)
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, check=False)
    return time.perf_counter() - t0


def in_turns(a: list[str], b: list[str], runs: int, env: dict[str, str]) -> tuple[list[float], list[float]]:
    """`runs` timings of each, taken in turns after one untimed run of each (file and tool caches)."""
    wall(a, env=env)
    wall(b, env=env)
    times_a, times_b = [], []
    for _ in range(runs):
        times_a.append(wall(a, env=env))
        times_b.append(wall(b, env=env))
    return times_a, times_b


def ratio(times_a: list[float], times_b: list[float]) -> float:
    """Median of the ratios of runs taken side by side."""
    return statistics.median(x / y for x, y in zip(times_a, times_b, strict=True))


def load() -> str:
    try:
        return Path("/proc/loadavg").read_text(encoding="utf-8").split()[0]
    except OSError:
        return "?"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=15, help="validate runs of each kind (default 15)")
    parser.add_argument("--gen-runs", type=int, default=3, help="gen runs of each size (default 3)")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores, load {load()}")

    floor = [PY, "-c", "pass"]
    validate = [*CLI, "validate", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--no-cache"]
    no_cache = {**ENV, "TD2ADAPTOR_NO_CACHE": "1"}
    for label, env in (("--no-cache", ENV), ("TD2ADAPTOR_NO_CACHE=1", no_cache)):
        runs, base = in_turns(validate, floor, args.runs, env)
        print(
            f"validate RB-1, fresh process, {label:<22} {statistics.median(runs) * 1000:7.1f} ms   python -c pass "
            f"{statistics.median(base) * 1000:6.1f} ms   ratio {ratio(runs, base):5.2f}   target <= 200 ms"
        )

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cmds = {}
        for n in (1000, 10000):
            (work / f"synth{n}.json").write_text(json.dumps(synthetic_td(n)), encoding="utf-8")
            cmds[n] = [*CLI, "gen", f"synth{n}.json", "-o", f"out{n}", "--partial", "--no-cache"]
        small, large = [], []
        wall(cmds[1000], cwd=work, before=work / "out1000")  # untimed: file and tool caches
        for _ in range(args.gen_runs):
            small.append(wall(cmds[1000], cwd=work, before=work / "out1000"))
            large.append(wall(cmds[10000], cwd=work, before=work / "out10000"))
        files = sum(1 for p in (work / "out10000").rglob("*") if p.is_file())
        print(
            f"gen all backends, 10,000 affordances ({files} files) {statistics.median(large):7.2f} s   "
            f"1,000 affordances {statistics.median(small):6.2f} s   ratio {ratio(large, small):5.2f}   "
            "target <= 10.5 (linear: 10)"
        )
    print(f"load at the end {load()}")


if __name__ == "__main__":
    main()
