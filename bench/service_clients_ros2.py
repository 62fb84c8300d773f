"""Concurrent calls to one ROS 2 service through the generated rclpy adaptor (issue 17): calls per second and
calls never answered, next to one thread calling alone (the baseline, same run).

Each scenario has `threads` threads calling `call_gotoQuery` of one simulated RB-1 (the same service) through
`clients` component objects (each its own rclpy client; every client of a service also receives the others'
responses and discards them). A call never answered ends with `CallTimeout` after `--timeout` seconds and is
counted as lost. What it showed (see the package README's note on concurrency): up to 8 in flight nothing is
lost, through one client or two; beyond the server's request history (rclpy's default services QoS, KEEP_LAST
10) requests are lost whatever the client does.

The robot is the simulated RB-1 (examples/robotnik_rb1/sim/ros2.py) in its own process; the callers and the
node's `spin_in_background` are in this process. Needs the ROS 2 extra.
Run: `.venv/bin/python bench/service_clients_ros2.py [--calls N] [--rounds R] [--timeout S]`.
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import EXAMPLE, Process, generate_rclpy  # noqa: E402

NS = "rb1_clients_bench"
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}]}}
#: (threads, clients) of each scenario; the first is the baseline
SCENARIOS = ((1, 1), (8, 1), (8, 2), (16, 1), (16, 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--calls", type=int, default=1600, help="calls per round and scenario")
    parser.add_argument("--rounds", type=int, default=5, help="rounds, scenarios interleaved in each")
    parser.add_argument("--timeout", type=float, default=2.0, help="seconds before a call counts as lost")
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    env.isolate()
    prefix = build_interfaces()
    env.load_prefix(prefix)
    src = generate_rclpy(EXAMPLE / "td.json", Path(tempfile.mkdtemp(prefix="td2adaptor-bench-clients-")) / "src")
    sys.path.insert(0, str(src))
    adaptor: Any = importlib.import_module(src.name)
    sim = Process([sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--namespace", NS], env.child_env([prefix]))
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("clients_bench", context=context)
    spinner = adaptor.spin_in_background(node)
    try:
        sim.wait_for(lambda e: e.get("event") == "ready", 30)
        run(adaptor, node, args.calls, args.rounds, args.timeout)
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)
        sim.stop()


def run(adaptor: Any, node: Any, calls: int, rounds: int, timeout: float) -> None:
    components = [adaptor.GoToComponent(node, NS, timeout=timeout, wait_timeout=20.0) for _ in range(2)]
    mission = int(components[0].call_gotoRun(components[0].construct_gotoRun_Msg(**GOAL)).mission_id)
    for component in components:
        component.call_gotoQuery(mission_id=mission)  # registered, the server seen
    rates: dict[tuple[int, int], list[float]] = {s: [] for s in SCENARIOS}
    lost: dict[tuple[int, int], int] = dict.fromkeys(SCENARIOS, 0)
    for _ in range(rounds):
        for threads, clients in SCENARIOS:
            rate, missing = scenario(components[:clients], threads, calls, mission, adaptor.CallTimeout)
            rates[threads, clients].append(rate)
            lost[threads, clients] += missing
    base = statistics.median(rates[SCENARIOS[0]])
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {rounds} rounds of {calls} calls each")
    print(f"{'threads':>8} {'clients':>8} {'calls/s':>10} {'vs 1 thread':>12} {'lost':>8}")
    for threads, clients in SCENARIOS:
        rate = statistics.median(rates[threads, clients])
        print(f"{threads:>8} {clients:>8} {rate:>10.0f} {rate / base:>11.2f}x {lost[threads, clients]:>8}")
    print(f"(lost: calls never answered within {timeout:g} s, of {rounds * calls} per scenario; medians of calls/s)")


def scenario(components: list[Any], threads: int, calls: int, mission: int, timeout_error: type) -> tuple[float, int]:
    """Calls per second of `threads` threads sharing `calls` calls over `components`, and the calls lost."""
    per = calls // threads
    go = threading.Barrier(threads + 1)
    missing = [0] * threads

    def work(lane: int) -> None:
        call = components[lane % len(components)].call_gotoQuery
        go.wait()
        for _ in range(per):
            try:
                call(mission_id=mission)
            except timeout_error:
                missing[lane] += 1

    workers = [threading.Thread(target=work, args=(lane,)) for lane in range(threads)]
    for worker in workers:
        worker.start()
    go.wait()
    t0 = time.perf_counter()
    for worker in workers:
        worker.join()
    return per * threads / (time.perf_counter() - t0), sum(missing)


if __name__ == "__main__":
    main()
