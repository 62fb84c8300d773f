"""Edge node on real ROS 1 through the bridge (issue 31). Every figure is printed next to baselines measured in
the same run.

* query latency: query event → the ROS 1 bridge (a /usr/bin/python3 child running the generated rospy
  package) → `call_gotoQuery` → state event over a real mosquitto, against the direct call (the generated
  package's `call_gotoQuery` in a rospy process of its own) plus the MQTT echo (an MQTT client of the edge
  node's kind that publishes each request back on the answer topic, no engine, no ROS): one query at a time
  the edge node's answer needs both, one after the other, so direct + echo is its floor (issue 31's goal:
  median ≤ floor + 0.3 ms, as on ROS 2, bench/edge_node_ros2.py). The three are interleaved in blocks of 10.

The robot is the simulated RB-1 (examples/robotnik_rb1/sim/ros1.py) on a private rosmaster. Needs Debian's
ROS 1 (`SUDO= bash .ci/setup-ros1.sh`) and mosquitto. Run: `.venv/bin/python bench/edge_node_ros1.py [--runs N]`.
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

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from edge_node_ros2 import ECHO, GOAL, Echo  # noqa: E402
from runtime_bus import Replies, model, mosquitto  # noqa: E402

from td2adaptor.runtime import RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.bus.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.bus.security import parse_broker_url  # noqa: E402
from td2adaptor.runtime.ros.bridge import Ros1Bridge  # noqa: E402
from td2adaptor.runtime.ros.genport import Layout  # noqa: E402
from tests import generated  # noqa: E402
from tests.ros1 import harness  # noqa: E402

EXAMPLE = REPO / "examples" / "robotnik_rb1"
PKG = "robotnik_rb_1_adaptor"
NS = "rb1_edge_bench_ros1"
ROOT = f"td2adaptor/{NS}/GoToComponent"
BLOCK = 10  # calls of each kind per interleaved block

#: the direct client (Debian's python): a mission to query, then one line of timings per "N" line read
DIRECT = r"""
import json, sys, time, rospy
rospy.init_node("td2adaptor_bench_direct", anonymous=True, disable_signals=True)
from robotnik_rb_1_adaptor import GoToComponent
goto = GoToComponent(sys.argv[1])
goto.register()
started = goto.call_gotoRun(goto.construct_gotoRun_Msg(procedure={"goals": [{"pose": {"x": 1.0}}]}))
mid = int(started.mission_id)
print(json.dumps({"mission": mid}), flush=True)
for line in sys.stdin:
    if not line.strip():
        break
    times = []
    for _ in range(int(line)):
        t0 = time.perf_counter()
        goto.call_gotoQuery(mission_id=mid)
        times.append(time.perf_counter() - t0)
    print(json.dumps(times), flush=True)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=300)
    args = parser.parse_args()
    problem = harness.ros1_problem()
    if problem:
        print(f"ROS 1 edge-node benchmark skipped: {problem}")
        return
    with tempfile.TemporaryDirectory(prefix="td2adaptor-bench-ros1-") as tmp:
        root = Path(tmp)
        _, package = generated.generate("rospy", EXAMPLE / "td.json", root / "pkg", interfaces=[EXAMPLE / "interfaces"])
        interfaces = harness.interfaces_dir()
        path = [interfaces, package / "src"]
        with harness.rosmaster(root / "home") as master, harness.run_sim(master, interfaces, NS, "--duration", "0.2"):
            run(master, path, args.runs)


def run(master: harness.Master, path: list[Path], runs: int) -> None:
    direct = subprocess.Popen(
        [harness.SYSTEM_PYTHON, "-c", DIRECT, NS],
        env=master.env(*path),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    assert direct.stdin is not None and direct.stdout is not None
    mid = int(json.loads(direct.stdout.readline())["mission"])
    m = model()
    bridge = Ros1Bridge(
        Layout.of(m),
        PKG,
        [(NS, NS)],
        python=harness.SYSTEM_PYTHON,
        pythonpath=[*path],
        master_uri=master.uri,
        timeout=5.0,
        environ=master.env(),
    )
    bridge.start()
    version = subprocess.run([harness.SYSTEM_PYTHON, "-V"], capture_output=True, text=True).stdout.split()[-1]
    today = time.strftime("%Y-%m-%d")
    print(f"python {sys.version.split()[0]} (bridge: Debian python {version}), {today}, {runs} runs")
    direct_q: list[float] = []
    event_q: list[float] = []
    echo_q: list[float] = []
    with mosquitto() as url:
        config = RuntimeConfig(robot=NS, bus=url, poll_period=0.01, property_period=0, call_timeout=5.0)
        engine = serve(m, bridge.port(NS), config)
        replies = Replies()
        app = MqttBus(parse_broker_url(url), client_id="edge-bench-ros1-app", clean_start=True)
        app.subscribe(f"{ROOT}/gotoRun/+", replies)
        app.subscribe(f"{ECHO}/{ROOT}/gotoRun/+", replies)
        app.connect()
        echo = Echo(url)

        def answered_in(root: str, corr: str) -> float:
            t0 = time.perf_counter()
            app.publish(f"{root}/gotoQuery", json.dumps({"correlation": corr, "mission": mid}).encode())
            replies.wait(lambda: corr in replies.by_corr)
            return time.perf_counter() - t0

        def direct_block(n: int) -> list[float]:
            assert direct.stdin is not None and direct.stdout is not None
            direct.stdin.write(f"{n}\n")
            direct.stdin.flush()
            return [float(t) for t in json.loads(direct.stdout.readline())]

        try:
            app.publish(f"{ROOT}/gotoRun", json.dumps({"correlation": "warm", "payload": GOAL}).encode())
            replies.wait(lambda: "warm" in replies.by_corr, 30)
            for i in range(3 * BLOCK):  # warm-up: connections made, caches filled
                answered_in(ROOT, f"w{i}")
                answered_in(f"{ECHO}/{ROOT}", f"we{i}")
            direct_block(3 * BLOCK)
            for b in range(max(1, runs // BLOCK)):  # interleaved blocks: the three see the same machine state
                direct_q.extend(direct_block(BLOCK))
                for i in range(BLOCK):
                    event_q.append(answered_in(ROOT, f"q{b}-{i}"))
                    echo_q.append(answered_in(f"{ECHO}/{ROOT}", f"e{b}-{i}"))
        finally:
            engine.stop()
            app.close()
            echo.close()
            bridge.close()
            direct.stdin.write("\n")
            direct.stdin.flush()
            direct.wait(30)
    med = statistics.median
    edge_ms, direct_ms, echo_ms = med(event_q) * 1e3, med(direct_q) * 1e3, med(echo_q) * 1e3
    floor = direct_ms + echo_ms
    print(f"{'query event -> ROS 1 bridge -> state event':<46} {edge_ms:8.3f} ms   (medians)")
    print(f"{'direct call_gotoQuery (rospy process)':<46} {direct_ms:8.3f} ms")
    print(f"{'MQTT echo alone':<46} {echo_ms:8.3f} ms")
    print(
        f"{'edge - (direct + echo)':<46} {edge_ms - floor:+8.3f} ms   edge / (direct + echo) "
        f"{edge_ms / floor:4.2f}x   target <= +0.3 ms"
    )
    print(f"  ({len(event_q)} queries each, in interleaved blocks of {BLOCK}; load average {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
