"""rclpy backend benchmarks (issue 3). Every figure is printed next to a baseline measured in the same run.

* `call_X` round trip of the generated package vs a hand-written minimal rclpy client making the same call
  (`client.call(request, timeout_sec=...)` after one `wait_for_service`) to the same simulated RB-1, from the
  same node and executor (a SingleThreadedExecutor spinning in a background thread), samples interleaved
  (target ratio <= 1.05).
* `construct_X_Msg` vs building the same request directly with the rosidl classes (target <= 1.2x).
* `td2adaptor gen` of the RB-1 example, rclpy only, in a new process each time (with an empty and with a warm
  result cache), next to `td2adaptor --version` (the CLI's start-up) and `td2adaptor validate` of the same TD.

Needs the ROS 2 extra (`SUDO= bash .ci/setup-ros2.sh`); builds the RB-1 interfaces once (cached in .cache/).
Run: `.venv/bin/python bench/backend_rclpy.py [--rounds N] [--block N]`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import subprocess
import sys
import tempfile
import time
import timeit
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces, colcon_build  # noqa: E402
from tests.ros2.common import EXAMPLE, PACKAGE, Process, generate_rclpy  # noqa: E402

NS = "rb1_bench"
TD2ADAPTOR = str(Path(sys.executable).with_name("td2adaptor"))


def median_us(samples: list[float]) -> float:
    return statistics.median(samples) * 1e6


def bench_calls(adaptor: Any, rounds: int, block: int) -> None:
    import rclpy
    from procedures_msgs.msg import ProcedureHeader
    from procedures_msgs.srv import ProcedureQuery, ProcedureQuery_Request
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("bench_client", context=context)
    spinner = adaptor.spin_in_background(node)
    try:
        goto = adaptor.GoToComponent(node, NS, timeout=5.0, wait_timeout=20.0)
        started = goto.call_gotoRun(goto.construct_gotoRun_Msg(procedure={"goals": [{"pose": {"x": 1.0}}]}))
        request = ProcedureQuery_Request(header=ProcedureHeader(id=started.mission_id))
        name = f"/{NS}/robot_local_control/NavigationComponent/GoToComponent/query_state"
        minimal = node.create_client(ProcedureQuery, name)
        assert minimal.wait_for_service(timeout_sec=20.0)
        variants: dict[str, Callable[[], Any]] = {
            "generated call_gotoQuery": lambda: goto.call_gotoQuery(request),
            "hand-written client.call": lambda: minimal.call(request, timeout_sec=5.0),
        }
        for call in variants.values():  # warm up: connections matched, caches filled
            for _ in range(50):
                assert call().state.header.id == started.mission_id
        samples: dict[str, list[float]] = {k: [] for k in variants}
        for _ in range(rounds):
            for key, call in variants.items():  # interleaved, so drift hits both alike
                for _ in range(block):
                    t0 = time.perf_counter()
                    call()
                    samples[key].append(time.perf_counter() - t0)
        generated, minimal_us = (median_us(samples[k]) for k in variants)
        print(f"service round trip, 2 processes, {rounds * block} calls each (median):")
        for key in variants:
            s = sorted(samples[key])
            print(f"  {key:28s} {median_us(s):8.1f} us   p95 {s[int(len(s) * 0.95)] * 1e6:8.1f} us")
        print(f"  ratio generated / hand-written: {generated / minimal_us:.3f}   (target <= 1.05)")

        from procedures_msgs.msg import ProcedureHeader as Header
        from robot_local_control_msgs.msg import GoTo, Pose2DStamped
        from robot_local_control_msgs.srv import GoToPetition_Request

        header = Header(id=7)
        goal = GoTo(goals=[Pose2DStamped()])
        pairs = {
            "gotoQuery (header=msg)": (
                lambda: goto.construct_gotoQuery_Msg(header=header),
                lambda: ProcedureQuery_Request(header=header),
            ),
            "gotoRun (procedure=msg)": (
                lambda: goto.construct_gotoRun_Msg(procedure=goal),
                lambda: GoToPetition_Request(procedure=goal),
            ),
        }
        print("construct_X_Msg vs the rosidl constructor (best of 7 x 20000):")
        for label, (ours, direct) in pairs.items():
            best = {"ours": float("inf"), "direct": float("inf")}
            for _ in range(7):  # interleaved repeats, best of each
                best["ours"] = min(best["ours"], timeit.timeit(ours, number=20000) / 20000)
                best["direct"] = min(best["direct"], timeit.timeit(direct, number=20000) / 20000)
            t_ours, t_direct = best["ours"], best["direct"]
            print(
                f"  {label:26s} generated {t_ours * 1e6:6.2f} us   direct {t_direct * 1e6:6.2f} us   "
                f"ratio {t_ours / t_direct:.3f}   (target <= 1.2)"
            )
        mapping = min(
            timeit.repeat(lambda: goto.construct_gotoRun_Msg(procedure={"goals": [{"pose": {"x": 1.0}}]}), number=5000)
        )
        print(f"  gotoRun from a nested dict (no direct equivalent): {mapping / 5000 * 1e6:.2f} us")
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)


def bench_cli(runs: int) -> None:
    td = str(EXAMPLE / "td.json")
    interfaces = str(EXAMPLE / "interfaces")

    def timed(args: list[str], *, warm: bool) -> float:
        """Median wall time of `td2adaptor ARGS` in a new process; warm: with a filled result cache."""
        times = []
        with tempfile.TemporaryDirectory() as keep:
            for i in range(runs + (1 if warm else 0)):
                with tempfile.TemporaryDirectory() as tmp:
                    cache = Path(keep if warm else tmp) / "cache"
                    environ = {**os.environ, "TD2ADAPTOR_CACHE_DIR": str(cache)}
                    t0 = time.perf_counter()
                    subprocess.run(
                        [TD2ADAPTOR, *[a.replace("{out}", str(Path(tmp) / "out")) for a in args]],
                        check=True,
                        capture_output=True,
                        env=environ,
                    )
                    if not (warm and i == 0):
                        times.append(time.perf_counter() - t0)
        return statistics.median(times)

    gen = ["gen", td, "-I", interfaces, "-o", "{out}", "--backend", "rclpy"]
    validate = ["validate", td, "-I", interfaces]
    print(f"CLI, a new process each run (median of {runs}):")
    print(
        f"  td2adaptor --version                         {timed(['--version'], warm=False) * 1e3:7.1f} ms   (start-up)"
    )
    for warm in (False, True):
        label = "warm cache" if warm else "empty cache"
        print(
            f"  td2adaptor validate RB-1, {label:11s}        {timed(validate, warm=warm) * 1e3:7.1f} ms   (front end)"
        )
        print(f"  td2adaptor gen RB-1 --backend rclpy, {label:11s} {timed(gen, warm=warm) * 1e3:7.1f} ms")


def main() -> int:
    parser = argparse.ArgumentParser(description="rclpy backend benchmarks")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--block", type=int, default=100)
    parser.add_argument("--cli-runs", type=int, default=7)
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 (pip extra ros2) is not installed: skipped (SUDO= bash .ci/setup-ros2.sh)")
        return 0
    env.isolate()
    prefix = build_interfaces()
    env.load_prefix(prefix)
    with tempfile.TemporaryDirectory(prefix="bench-rclpy-") as tmp:
        base = Path(tmp)
        generate_rclpy(EXAMPLE / "td.json", base / "src")
        install = colcon_build(base, [prefix], cmake=False)
        sys.path.insert(0, str(env.site_packages(install)))
        adaptor = importlib.import_module(PACKAGE)
        sim = Process(
            [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--namespace", NS, "--duration", "1.0"],
            env.child_env([prefix]),
        )
        try:
            sim.wait_for(lambda e: e.get("event") == "ready", timeout=30)
            bench_calls(adaptor, args.rounds, args.block)
        finally:
            sim.stop()
    bench_cli(args.cli_runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
