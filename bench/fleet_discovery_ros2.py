"""What `td2adaptor run --discover` costs at idle (issue 32): one reading of the ROS 2 graph every half second,
with N simulated RB-1s in it, in CPU of one core.

The robots are the RB-1 simulation (`--count N`, one process, rclpy's EventsExecutor); this process reads the
graph as the edge node does (`runtime/node/graphwatch.py`'s `Ros2Graph` on an rclpy node that is not spun),
first with no robot known (every namespace checked in full: the look that finds them), then with all of them
known (served: each checked by its first service only, the steady state), and reports the CPU time of the
looks (`time.process_time`, this process only) per look and as a share of one core at the edge node's period;
then the glance at the graph's nodes discovery takes every `GRAPH_GAP` between two looks (`Ros2Graph.stamp`:
a robot that appears is looked for at once), and the whole of it as the edge node runs it: a `Discovery` with
every robot served, the process's CPU over `--seconds` with it running minus the same without it.
Needs the ROS 2 extra. Run: `.venv/bin/python bench/fleet_discovery_ros2.py [--robots 100] [--seconds 10]`.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import Process  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, default=100, help="simulated robots in the graph")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long each mode looks")
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    env.isolate()
    prefix = build_interfaces()
    env.load_prefix(prefix)
    import td2adaptor
    from td2adaptor.runtime.node import graphwatch
    from td2adaptor.runtime.node.graphwatch import PERIOD, Discovery, Ros2Graph, robot_id, signature

    result = td2adaptor.compile(
        REPO / "examples/robotnik_rb1/rb1.tm.json", interfaces=[REPO / "examples/robotnik_rb1/interfaces"]
    )
    assert result.model is not None
    sig = signature(result.model)
    cmd = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--namespace", "disc_bench"]
    cmd += ["--count", str(args.robots), "--executor", "events", "--quiet"]
    sim = Process(cmd, env.child_env([prefix]))
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    try:
        sim.wait_for(lambda e: e.get("event") == "ready", timeout=300)
        node = rclpy.create_node("discovery_bench", context=context)
        graph = Ros2Graph(node)
        deadline = time.monotonic() + 120
        found: set[str] = set()
        while len(found) < args.robots and time.monotonic() < deadline:
            found = graph.robots(sig, set())
            time.sleep(0.2)
        print(f"{len(found)} of {args.robots} robots in the graph")
        for label, known in (("finding (none known)", set()), ("steady (all known)", found)):
            looks, cpu = 0, 0.0
            end = time.monotonic() + args.seconds
            while time.monotonic() < end:
                before = time.process_time()
                seen = graph.robots(sig, known)
                cpu += time.process_time() - before
                looks += 1
                assert len(seen) == len(found), (len(seen), len(found))
            per = cpu / looks
            print(
                f"{label}: {per * 1000:.2f} ms CPU per look, "
                f"{100 * per / PERIOD:.2f} % of one core at one look per {PERIOD} s"
            )
        stamp = getattr(graph, "stamp", None)  # None: a version that reads the graph every period only
        if stamp is not None:
            gap = float(getattr(graphwatch, "GRAPH_GAP", 0.1))
            glances, cpu = 0, 0.0
            end = time.monotonic() + args.seconds
            while time.monotonic() < end:
                before = time.process_time()
                stamp()
                cpu += time.process_time() - before
                glances += 1
            per = cpu / glances
            print(
                f"glance at the graph's nodes: {per * 1000:.3f} ms CPU, "
                f"{100 * per / gap:.2f} % of one core at one glance per {gap} s"
            )
        idle = _idle_cpu(args.seconds)
        served = _Served({robot_id(ns) or ns: ns for ns in found})
        discovery = Discovery(served, graph, sig, _config, grace=10.0)
        discovery.start()
        time.sleep(1.0)  # the first look, which finds them all
        scans = discovery.scans
        busy = _idle_cpu(args.seconds)
        scans = discovery.scans - scans
        discovery.stop()
        print(
            f"discovery running, every robot served: {100 * (busy - idle):.2f} % of one core "
            f"(the process {100 * busy:.2f} %, without discovery {100 * idle:.2f} %), {scans} looks in "
            f"{args.seconds:g} s"
        )
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
        sim.stop()


def _idle_cpu(seconds: float) -> float:
    """This process's CPU (every thread: DDS's too) over `seconds` of wall time, as a share of one core."""
    cpu, wall = time.process_time(), time.monotonic()
    time.sleep(seconds)
    return (time.process_time() - cpu) / (time.monotonic() - wall)


def _config(robot: str, namespace: str) -> Any:
    from td2adaptor.runtime.config import RuntimeConfig

    return RuntimeConfig(robot=robot, namespace=namespace)


class _Served:
    """The fleet discovery hands its robots to, serving every robot found already (the steady state)."""

    def __init__(self, namespaces: dict[str, str]) -> None:
        self.served = {robot: _config(robot, ns) for robot, ns in namespaces.items()}

    def robots(self, origin: str | None = None) -> dict[str, Any]:
        return dict(self.served)

    def origin(self, robot: str) -> str | None:
        return "discovery" if robot in self.served else None

    def apply(self, configs: list[Any], origin: str) -> Any:
        from td2adaptor.runtime.node.fleet import Changes

        self.served = {c.robot: c for c in configs}
        return Changes()


if __name__ == "__main__":
    main()
