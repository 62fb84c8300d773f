"""Edge node on real ROS 2 (issue 5). Every figure is printed next to a baseline measured in the same run.

* latency: query event → `call_gotoQuery` on ROS 2 → state event over a real mosquitto, and invoke event →
  `call_gotoRun` → first feedback, vs calling the generated component's `call_X` directly from the same
  node (target: overhead <= 2 ms median); the `GeneratedPort` alone, vs the same direct call;
* throughput: query events one edge node answers per second over MQTT, vs direct `call_gotoQuery` per second;
* bus messages per goto action (1 invoke + one feedback per state change), vs the reference's 2.

The robot is the simulated RB-1 (examples/robotnik_rb1/sim/ros2.py) in its own process; the edge node (engine,
MQTT client, rclpy node) and the application (a second MQTT client) are in this process.
Needs the ROS 2 extra and mosquitto. Run: `.venv/bin/python bench/edge_node_ros2.py [--runs N]`.
"""

from __future__ import annotations

import argparse
import importlib
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from runtime_bus import Replies, latency, model, mosquitto  # noqa: E402

from td2adaptor.runtime import RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.genport import GeneratedPort  # noqa: E402
from td2adaptor.runtime.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.security import parse_broker_url  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import EXAMPLE, Process, generate_rclpy  # noqa: E402

NS = "rb1_edge_bench"
ROOT = f"td2adaptor/{NS}/GoToComponent"
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}]}}
FLOOD = 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=300)
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    env.isolate()
    prefix = build_interfaces()
    env.load_prefix(prefix)
    work = Path(tempfile.mkdtemp(prefix="td2adaptor-bench-edge-"))
    src = generate_rclpy(EXAMPLE / "td.json", work / "src")
    sys.path.insert(0, str(src))
    adaptor: Any = importlib.import_module(src.name)
    sim = Process(
        [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--namespace", NS, "--duration", "0.2"],
        env.child_env([prefix]),
    )
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("edge_bench", context=context)
    spinner = adaptor.spin_in_background(node)
    try:
        sim.wait_for(lambda e: e.get("event") == "ready", 30)
        run(adaptor, node, args.runs)
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)
        sim.stop()


def run(adaptor: Any, node: Any, runs: int) -> None:
    m = model()
    goto = adaptor.GoToComponent(node, NS, timeout=5.0, wait_timeout=20.0)
    port = GeneratedPort(m, adaptor, NS, distro="ros2", node=node, timeout=5.0, wait_timeout=20.0)
    first = goto.call_gotoRun(goto.construct_gotoRun_Msg(**GOAL))
    time.sleep(0.4)  # finished
    mid = first.mission_id
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {runs} runs, flood of {FLOOD}")
    with mosquitto() as url:
        config = RuntimeConfig(robot=NS, bus=url, poll_period=0.01, property_period=0, call_timeout=5.0)
        engine = serve(m, port, config)
        replies = Replies()
        app = MqttBus(parse_broker_url(url), client_id="edge-bench-app", clean_start=True)
        app.subscribe(f"{ROOT}/gotoRun/+", replies)
        app.connect()

        def send(topic: str, event: dict[str, Any]) -> None:
            app.publish(topic, json.dumps(event).encode())

        direct_q, port_q, event_q = [], [], []
        try:
            for i in range(runs):  # interleaved: the three see the same machine state
                t0 = time.perf_counter()
                goto.call_gotoQuery(mission_id=mid)
                direct_q.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                port.query("GoToComponent", "gotoQuery", mid, 5.0)
                port_q.append(time.perf_counter() - t0)
                corr = f"q{i}"
                t0 = time.perf_counter()
                send(f"{ROOT}/gotoQuery", {"correlation": corr, "mission": mid})
                replies.wait(lambda c=corr: c in replies.by_corr)  # type: ignore[misc]
                event_q.append(time.perf_counter() - t0)
            direct_s, event_s, per_action = [], [], []
            for i in range(max(5, runs // 30)):
                t0 = time.perf_counter()
                started = goto.call_gotoRun(goto.construct_gotoRun_Msg(**GOAL))
                direct_s.append(time.perf_counter() - t0)
                goto.call_gotoCancel(mission_id=started.mission_id)
                corr = f"g{i}"
                t0 = time.perf_counter()
                send(f"{ROOT}/gotoRun", {"correlation": corr, "payload": GOAL})
                replies.wait(lambda c=corr: c in replies.by_corr)  # type: ignore[misc]
                event_s.append(time.perf_counter() - t0)
                replies.wait(lambda c=corr: any(e["payload"].get("terminal") for e in replies.by_corr[c]))  # type: ignore[misc]
                per_action.append(1 + len(replies.by_corr[corr]))
            t0 = time.perf_counter()
            for _ in range(FLOOD):
                goto.call_gotoQuery(mission_id=mid)
            direct_rate = FLOOD / (time.perf_counter() - t0)
            start = replies.count
            t0 = time.perf_counter()
            for i in range(FLOOD):
                send(f"{ROOT}/gotoQuery", {"correlation": f"f{i}", "mission": mid})
            replies.wait(lambda: replies.count - start >= FLOOD, timeout=120)
            rate = FLOOD / (time.perf_counter() - t0)
        finally:
            engine.stop()
            app.close()
    med = statistics.median
    target = "<= 2 ms"
    latency("query event -> ROS 2 -> state event, MQTT", med(event_q), "call_gotoQuery", med(direct_q), target)
    latency("invoke event -> ROS 2 -> 1st feedback, MQTT", med(event_s), "call_gotoRun", med(direct_s), target)
    latency("GeneratedPort.query (dicts in and out)", med(port_q), "call_gotoQuery", med(direct_q))
    label = "query events answered per s, MQTT + ROS 2"
    print(f"{label:<44} {rate:8.0f} /s   {'call_gotoQuery':<20} {direct_rate:7.0f} /s")
    print(
        f"{'bus messages per goto action':<44} {statistics.mean(per_action):8.1f}      {'reference edge node':<20} "
        f"{2:7d}      (1 invoke + queued, running, finished)"
    )


if __name__ == "__main__":
    main()
