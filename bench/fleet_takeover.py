"""What a kill -9 of one process of a shared fleet costs (issue 32, `run --share`, runtime/node/share.py): the
time until its robots are served again by the others, and the missions it touched, under one mission per
second per robot.

Real mosquitto, real processes (tests/runtime/share_proc.py: a `Fleet` and a `Share` whose robots are
simulated, `SimPort`, 0.3 s missions), sharing one state directory as processes on one machine do. For each
case: start the processes, wait until every robot is served and the shares are even, send the load for 3 s,
SIGKILL one process, send 3 s more, then wait for every invoke's terminal event.

Reported per case: takeover (kill -> the robot's `online` status from a survivor, over the killed process's
robots: median, p99, max), invokes sent, those of the killed process's robots that did not finish (`failed`:
the missions it was following, ended by the new owner's recovery when it cannot follow them again), and
missions run twice (from every process's log of the missions it started: must be 0).
Run: `.venv/bin/python bench/fleet_takeover.py [--case 30x2 --case 30x3 ...]` (default 30x2 and 30x3).

`--scenario N`: issue 32's whole scenario with real ROS 2 instead (three `run --share --discover` processes,
simulated RB-1s, N robots at the peak: 10 added, 5 removed, a SIGHUP, a kill -9 under missions, two bridged
brokers), which is too heavy for the test suite: tests/runtime/test_fleet_share_discover_ros2.py
`test_issue_32_scenario_at_scale`, run by pytest with TD2ADAPTOR_SHARE_SCENARIO_ROBOTS=N; its figures (one JSON
line) are printed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests.runtime.broker import Mosquitto  # noqa: E402
from tests.runtime.edge import until  # noqa: E402
from tests.runtime.test_fleet_share import Load, Procs, Watcher, served_by, shares  # noqa: E402


def case(robots: int, processes: int) -> dict[str, object]:
    with tempfile.TemporaryDirectory(prefix="td2adaptor-takeover-") as tmp:
        broker = Mosquitto(Path(tmp) / "broker")
        broker.start()
        procs = Procs(broker, Path(tmp), robots)
        watcher = Watcher(broker)
        load = Load(broker, [f"rb_{i:02d}" for i in range(robots)])
        try:
            started = procs.start_many(processes)
            pids = {p.pid for p in started}
            even = {robots // processes, -(-robots // processes)}
            ok = until(lambda: served_by(watcher, pids, robots) and set(shares(watcher, pids).values()) <= even, 120)
            assert ok, procs.logs()
            load.start()
            time.sleep(3)
            victim = started[0]
            theirs = {r for r, (_s, pid) in watcher.owners().items() if pid == victim.pid}
            killed = time.monotonic()
            victim.kill()
            victim.wait()
            survivors = pids - {victim.pid}
            assert until(lambda: served_by(watcher, survivors, robots), 60), procs.logs()
            back: dict[str, float] = {}
            for t, robot, p in watcher.statuses():
                if robot in theirs and t > killed and p.get("state") == "online" and p["owner"]["pid"] in survivors:
                    back.setdefault(robot, t - killed)
            time.sleep(3)
            load.stop()
            assert until(lambda: set(load.sent) <= set(watcher.terminals()), 60)
            ends = watcher.terminals()
            failed = [
                i for i, (robot, _t, _e) in load.sent.items() if robot in theirs and ends[i][0]["state"] != "finished"
            ]
            runs = procs.runs_of()
            times = sorted(back.values())
            return {
                "case": f"{robots} robots / {processes} processes",
                "takeover median": statistics.median(times),
                "takeover p99": times[min(len(times) - 1, int(len(times) * 0.99))],
                "takeover max": times[-1],
                "invokes": len(load.sent),
                "affected": len(failed),
                "run twice": sum(1 for n in runs.values() if n > 1),
                "states": dict(Counter(e[0]["state"] for e in ends.values())),
                "why": dict(
                    Counter(_why(e[0].get("message", "")) for e in ends.values() if e[0]["state"] != "finished")
                ),
            }
        finally:
            load.stop()
            watcher.close()
            procs.close()
            broker.stop()


def _why(message: str) -> str:
    """A failure's kind: `busy` (the robot's last mission was not over: load), `handed over`, `not known` (a
    mission followed again on another process's simulated robot, which does not know its id), or the message."""
    if "is busy with" in message:
        return "busy"
    if "handed over" in message:
        return "handed over"
    if message.startswith("no procedure with id"):
        return "not known"
    return message[:80]


def scenario(robots: int) -> int:
    """Issue 32's scenario at `robots` robots (see the module docstring); pytest's exit code."""
    test = "tests/runtime/test_fleet_share_discover_ros2.py::test_issue_32_scenario_at_scale"
    environ = {**os.environ, "TD2ADAPTOR_SHARE_SCENARIO_ROBOTS": str(robots), "PYTHONPATH": str(REPO)}
    command = [sys.executable, "-m", "pytest", "-n", "0", "-q", "-s", "-p", "no:cacheprovider", test]
    proc = subprocess.run(command, cwd=REPO, env=environ, capture_output=True, text=True, check=False)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("SCENARIO ")]
    print(*(lines or [proc.stdout[-3000:]]), sep="\n", flush=True)
    return proc.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--case", action="append", help="ROBOTSxPROCESSES (default: 30x2 and 30x3)")
    parser.add_argument("--scenario", type=int, help="issue 32's scenario with ROS 2 at this many robots (>= 12)")
    args = parser.parse_args()
    if args.scenario is not None:
        sys.exit(scenario(args.scenario))
    for spec in args.case or ["30x2", "30x3"]:
        robots, processes = (int(x) for x in spec.split("x"))
        r = case(robots, processes)
        print(
            f"{r['case']}: takeover median {r['takeover median']:.2f} s, p99 {r['takeover p99']:.2f} s, "
            f"max {r['takeover max']:.2f} s; {r['invokes']} invokes, {r['affected']} of the killed process's "
            f"robots not finished, {r['run twice']} run twice; {r['states']} {r['why'] or ''}",
            flush=True,
        )


if __name__ == "__main__":
    main()
