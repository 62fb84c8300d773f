"""`td2adaptor scaffold ros2` on large graphs (issue 15). Figures come with a baseline measured in the same run.

A synthetic ROS 2 graph runs in a child process (`--serve N`): N nodes in namespaces /bench_nNNN, each with 10
endpoints (4 publishers, 3 subscribers, 3 services; every node also has rclpy's parameter services and
/rosout, which the scaffold must leave out). For N = 10 (the baseline), 50 and 100 nodes (1,000 endpoints):

* read: one reading of the whole graph (every node's endpoints) through rclpy;
* layout + write: selection, names, components, the QoS of the endpoints described, schemas, the document:
  as a fleet (the N namespaces have the same interfaces: one Thing Model of 10 affordances), and as one TD
  describing all 10 x N endpoints (`--robot-namespace bench_n000`: the worst case, every topic's QoS read);
* CLI: `td2adaptor scaffold ros2` end to end in a fresh process (interpreter start, DDS discovery and the
  default 2 s settle window included).

Target: under 5 s for 100 nodes, and linear (time(100) / time(10) near 10). Needs the ROS 2 extra.
`--offline` (also what runs without ROS 2): the same graphs built in process as `graph.Graph` objects, no
rclpy, so the layout + write of td2adaptor itself is timed apart from rmw's graph queries (the single TD's
QoS reads, one rmw graph scan per topic, are what is left out there).
Run: `.venv/bin/python bench/scaffold.py [--runs N] [--offline]`.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from td2adaptor.diagnostics import Diagnostics  # noqa: E402
from td2adaptor.scaffold import (  # noqa: E402
    Options,
    ros2graph,  # noqa: E402
    scaffold,
)
from td2adaptor.scaffold.graph import Endpoint, Filters, Graph  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.common import Process  # noqa: E402

SIZES = (10, 50, 100)
PUBLISHED = ("state", "odom_x", "status_text", "level")
SUBSCRIBED = ("cmd", "enable", "speed")
SERVED = ("reset", "trigger", "set_mode")
TYPES = {
    "state": "std_msgs/msg/Float64", "odom_x": "std_msgs/msg/Float64", "status_text": "std_msgs/msg/String",
    "level": "std_msgs/msg/Float64", "cmd": "std_msgs/msg/Float64", "enable": "std_msgs/msg/Bool",
    "speed": "std_msgs/msg/Float64", "reset": "std_srvs/srv/Empty", "trigger": "std_srvs/srv/Trigger",
    "set_mode": "std_srvs/srv/SetBool",
}  # fmt: skip
LINEAR = 10 * 1.5  # growth for 10x the graph still called linear (fixed costs make it less than 10 at best)


def synthetic(n: int) -> Graph:
    """The graph `serve(n)` shows, built in process (no rclpy, no QoS)."""
    graph = Graph("the synthetic graph")
    for i in range(n):
        ns = f"/bench_n{i:03d}"
        for names, kind, role in ((PUBLISHED, "topic", "publisher"), (SUBSCRIBED, "topic", "subscriber"),
                                  (SERVED, "service", "server")):  # fmt: skip
            graph.endpoints += [Endpoint(kind, f"{ns}/{name}", TYPES[name], role, (f"{ns}/node",)) for name in names]  # type: ignore[arg-type]
    return graph


def offline(runs: int) -> None:
    """Layout + write of the synthetic graphs in process: the fleet TM and the one TD of every endpoint."""
    times: dict[int, dict[str, float]] = {}
    for n in SIZES:
        row: dict[str, list[float]] = {"fleet": [], "single": []}
        for _ in range(runs):
            for key, namespaces in (("fleet", ()), ("single", ("bench_n000",))):
                began = time.perf_counter()
                doc = scaffold(synthetic(n), Options(Filters(include=("^/bench_",)), namespaces), Diagnostics())
                json.dumps(doc)
                row[key].append(time.perf_counter() - began)
                assert doc is not None
        times[n] = {k: statistics.median(v) for k, v in row.items()}
    base, big = times[SIZES[0]], times[SIZES[-1]]
    print(f"{'nodes':>5} {'endpoints':>9} {'fleet TM':>9} {'x base':>6} {'one TD':>8} {'x base':>6}   (offline)")
    for n, t in times.items():
        print(f"{n:>5} {10 * n:>9} {t['fleet'] * 1000:>7.0f}ms {t['fleet'] / base['fleet']:>5.1f}x "
              f"{t['single'] * 1000:>6.0f}ms {t['single'] / base['single']:>5.1f}x")  # fmt: skip
    for key, label in (("fleet", "fleet TM"), ("single", "one TD")):
        ratio = big[key] / base[key]
        print(f"offline {label}: growth {ratio:.1f}x for 10x the graph (linear target <= {LINEAR:.0f}x: "
              f"{'linear' if ratio <= LINEAR else 'worse than linear'})")  # fmt: skip


def serve(n: int) -> int:
    """The synthetic graph: N nodes, 10 endpoints each, until SIGTERM."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Bool, Float64, String
    from std_srvs.srv import Empty, SetBool, Trigger

    context = Context()
    rclpy.init(context=context)
    nodes: list[Any] = []
    for i in range(n):
        node: Any = rclpy.create_node("node", namespace=f"/bench_n{i:03d}", context=context)
        for name, typ in zip(PUBLISHED, (Float64, Float64, String, Float64), strict=True):
            node.create_publisher(typ, name, 10)
        for name, typ in zip(SUBSCRIBED, (Float64, Bool, Float64), strict=True):
            node.create_subscription(typ, name, lambda _m: None, 10)
        for name, typ in zip(SERVED, (Empty, Trigger, SetBool), strict=True):
            node.create_service(typ, name, lambda _q, r: r)
        nodes.append(node)
    executor = SingleThreadedExecutor(context=context)
    for node in nodes:
        executor.add_node(node)
    print(json.dumps({"event": "ready", "nodes": n}), flush=True)
    try:
        executor.spin()
    except KeyboardInterrupt:
        pass
    return 0


def measure(n: int, runs: int) -> dict[str, float]:
    import rclpy
    from rclpy.context import Context

    child = Process([sys.executable, str(Path(__file__).resolve()), "--serve", str(n)], env.child_env([]))
    try:
        child.wait_for(lambda e: e.get("event") == "ready", timeout=120)
        context = Context()
        rclpy.init(context=context)
        node: Any = rclpy.create_node(ros2graph.NODE_NAME, context=context, start_parameter_services=False)
        try:
            # discovery is not what is measured: wait until every endpoint is seen
            deadline = time.monotonic() + 120
            while time.monotonic() < deadline:
                graph = ros2graph.graph_of(node, ros2graph._snapshot(node))
                if sum(e.name.startswith("/bench_") and "/_" not in e.name for e in graph.endpoints) >= 10 * n + 7 * n:
                    break
                time.sleep(0.2)
            reads, writes, singles = [], [], []
            for _ in range(runs):
                began = time.perf_counter()
                graph = ros2graph.graph_of(node, ros2graph._snapshot(node))
                read = time.perf_counter()
                diags = Diagnostics()
                doc = scaffold(graph, Options(Filters(include=("^/bench_",))), diags)
                json.dumps(doc)
                done = time.perf_counter()
                assert doc is not None and doc["@type"] == "tm:ThingModel", diags.codes()
                assert len(doc["properties"]) + len(doc["actions"]) == 10, doc.keys()
                reads.append(read - began)
                writes.append(done - read)
                began = time.perf_counter()
                graph = ros2graph.graph_of(node, ros2graph._snapshot(node))
                single = scaffold(graph, Options(Filters(include=("^/bench_",)), ("bench_n000",)), Diagnostics())
                json.dumps(single)
                singles.append(time.perf_counter() - began)
                assert single is not None and len(single["properties"]) + len(single["actions"]) == 10 * n
        finally:
            node.destroy_node()
            rclpy.shutdown(context=context)
        out = Path(tempfile.mkdtemp(prefix="td2adaptor-bench-scaffold-")) / "td.json"
        clis = []
        for _ in range(max(1, runs // 2)):
            began = time.perf_counter()
            cli = subprocess.run(
                [sys.executable, "-m", "td2adaptor", "scaffold", "ros2", "--include", "^/bench_",
                 "-o", str(out)],
                cwd=REPO, capture_output=True, text=True, timeout=300,
            )  # fmt: skip
            clis.append(time.perf_counter() - began)
            assert cli.returncode == 0, cli.stderr
        return {
            "read": statistics.median(reads),
            "write": statistics.median(writes),
            "total": statistics.median(r + w for r, w in zip(reads, writes, strict=True)),
            "cli": statistics.median(clis),
            "single": statistics.median(singles),
        }
    finally:
        child.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--offline", action="store_true", help="only the in-process synthetic graphs (no ROS 2)")
    parser.add_argument("--serve", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.serve:
        sys.exit(serve(args.serve))
    if args.offline or not env.ros2_available():
        if not args.offline:
            print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): offline figures only")
        offline(args.runs)
        return
    env.isolate()
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    results = {n: measure(n, args.runs) for n in SIZES}
    base = results[SIZES[0]]
    print(f"{'nodes':>5} {'endpoints':>9} {'read':>7} {'fleet TM':>9} {'total':>7} {'x base':>6} "
          f"{'one TD':>8} {'x base':>6} {'CLI':>7}")  # fmt: skip
    for n, r in results.items():
        print(
            f"{n:>5} {10 * n:>9} {r['read'] * 1000:>5.0f}ms {r['write'] * 1000:>7.0f}ms {r['total'] * 1000:>5.0f}ms "
            f"{r['total'] / base['total']:>5.1f}x {r['single'] * 1000:>6.0f}ms {r['single'] / base['single']:>5.1f}x "
            f"{r['cli']:>6.2f}s"
        )
    big = results[SIZES[-1]]
    ratio = big["total"] / base["total"]
    single = big["single"] / base["single"]
    fleet_verdict = "linear" if ratio <= LINEAR else "worse than linear"
    single_verdict = "linear" if single <= LINEAR else "worse than linear: rmw scans the graph for each QoS query"
    print(f"100 nodes / 1,000 endpoints: {big['total']:.2f} s in process, {big['cli']:.2f} s by the CLI "
          f"(target < 5 s: {'met' if big['cli'] < 5 else 'NOT met'}); growth for 10x the graph "
          f"(linear target <= {LINEAR:.0f}x): fleet TM {ratio:.1f}x ({fleet_verdict}), "
          f"one TD of 1,000 endpoints {single:.1f}x, {big['single']:.2f} s ({single_verdict})")  # fmt: skip
    offline(args.runs)


if __name__ == "__main__":
    main()
