"""A WoT consumer on real ROS 2 (issue 11). Every figure is printed next to a baseline measured in the same run.

* node-wot (Eclipse Thingweb, npm, Scripting API only) `invokeAction("gotoRun", goal)` → its terminal
  `gotoRunFeedback`, through the robot's published TD, mosquitto, the edge node (WoT adapter, engine,
  generated rclpy package) and the simulated RB-1 on ROS 2; next to the generated `call_gotoRun` followed by
  `call_gotoQuery` every poll period until the mission is terminal, from the edge node's own process (the
  same mission, the same poll period, no bus);
* the retained TD at start: `serve()` called → the TD received by a subscriber already waiting on the broker,
  next to the online status (published on the same connection, after the TD) and to `serve()` returning.

Needs the ROS 2 extra, mosquitto and node-wot (installed into .cache/node-wot by
.ci/setup-nodewot.sh). Run: `.venv/bin/python bench/wot_consumer.py [--runs N]`.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from runtime_bus import latency, model, mosquitto  # noqa: E402

from td2adaptor.runtime import RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.bus.bus import Message  # noqa: E402
from td2adaptor.runtime.bus.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.bus.security import parse_broker_url  # noqa: E402
from td2adaptor.runtime.ros.genport import GeneratedPort  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import EXAMPLE, Process, generate_rclpy  # noqa: E402

NS = "rb1_wot_bench"
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}]}}
POLL = 0.01
MODULES = REPO / ".cache" / "node-wot" / "node_modules"
SCRIPT = Path(__file__).parent / "nodewot_invoke.js"
TERMINAL = {"finished", "failed", "cancelled"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=30)
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    if not (MODULES / "@node-wot" / "binding-mqtt").is_dir():
        print(f"node-wot is not installed in {MODULES} (run bash .ci/setup-nodewot.sh): skipped")
        return
    env.isolate()
    prefix = build_interfaces()
    env.load_prefix(prefix)
    work = Path(tempfile.mkdtemp(prefix="td2adaptor-bench-wot-"))
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
    node: Any = rclpy.create_node("wot_bench", context=context)
    spinner = adaptor.spin_in_background(node)
    try:
        sim.wait_for(lambda e: e.get("event") == "ready", 30)
        run(adaptor, node, args.runs)
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)
        sim.stop()


def direct_run(goto: Any) -> float:
    """call_gotoRun, then call_gotoQuery every POLL until the mission is terminal: seconds."""
    t0 = time.perf_counter()
    started = goto.call_gotoRun(goto.construct_gotoRun_Msg(**GOAL))
    while True:
        time.sleep(POLL)
        answer = goto.call_gotoQuery(mission_id=started.mission_id)
        if str(answer.state.current_state) in TERMINAL:
            return time.perf_counter() - t0


def run(adaptor: Any, node: Any, runs: int) -> None:
    m = model()
    goto = adaptor.GoToComponent(node, NS, timeout=5.0, wait_timeout=20.0)
    port = GeneratedPort(m, adaptor, NS, distro="ros2", node=node, timeout=5.0, wait_timeout=20.0)
    direct_run(goto)  # warm up
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {runs} runs, poll period {POLL} s")
    with mosquitto() as url:
        arrived: dict[str, float] = {}
        seen = threading.Event()

        def watch(msg: Message) -> None:
            kind = msg.topic.rsplit("/", 1)[-1]
            if msg.payload and kind not in arrived:
                arrived[kind] = time.perf_counter()
                if {"td", "status"} <= set(arrived):
                    seen.set()

        watcher = MqttBus(parse_broker_url(url), client_id="wot-bench-watch", clean_start=True)
        watcher.subscribe(f"td2adaptor/{NS}/td", watch)
        watcher.subscribe(f"td2adaptor/{NS}/status", watch)
        watcher.connect()
        config = RuntimeConfig(robot=NS, bus=url, poll_period=POLL, property_period=0, call_timeout=5.0, state_dir="")
        t0 = time.perf_counter()
        engine = serve(m, port, config)
        returned = time.perf_counter()
        assert seen.wait(10), "the TD or the status did not arrive"
        try:
            before = [direct_run(goto) for _ in range(max(3, runs // 2))]
            out = subprocess.run(
                ["node", str(SCRIPT), url, NS, str(runs)],
                env={**os.environ, "NODE_PATH": str(MODULES)},
                capture_output=True,
                text=True,
                timeout=60 + runs * 5,
            )
            assert out.returncode == 0, out.stderr[-2000:]
            after = [direct_run(goto) for _ in range(max(3, runs // 2))]
        finally:
            engine.stop()
            watcher.close()
    wot = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    assert len(wot) == runs and all(r["state"] == "finished" for r in wot), wot
    med = statistics.median
    direct = before + after
    latency(
        "node-wot invokeAction -> terminal event",
        med(r["ms"] for r in wot) / 1000,
        "call_gotoRun+Query",
        med(direct),
    )
    print(
        f"{'  (sim mission 0.2 s; direct before/after)':<44} {med(before) * 1000:8.3f} ms / {med(after) * 1000:.3f} ms"
    )
    td_ms, status_ms, serve_ms = ((arrived["td"] - t0) * 1000, (arrived["status"] - t0) * 1000, (returned - t0) * 1000)
    print(
        f"{'retained TD at a subscriber after serve()':<44} {td_ms:8.3f} ms   {'online status':<20} {status_ms:7.3f} ms"
    )
    print(f"{'serve() returned':<44} {serve_ms:8.3f} ms")


if __name__ == "__main__":
    main()
