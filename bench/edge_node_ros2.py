"""Edge node on real ROS 2 (issue 5). Every figure is printed next to a baseline measured in the same run.

* latency: query event → `call_gotoQuery` on ROS 2 → state event over a real mosquitto, and invoke event →
  `call_gotoRun` → first feedback, vs calling the generated component's `call_X` directly from the same
  node (target: overhead <= 2 ms median); the `GeneratedPort` alone, vs the same direct call;
* throughput: query events one edge node answers per second over MQTT, vs direct `call_gotoQuery` per second;
* issue 17: query latency median and p99, edge node vs direct (target: median <= 1.3x), and throughput with 8
  requests in flight spread over the three procedure components of two robots (two namespaces the sim
  serves, one edge node serving both), vs 8 threads calling the generated components directly (target:
  >= 0.8x), rounds interleaved; beside both, the same requests answered by an echo (an MQTT client that
  publishes each request back, unread, on the answer topic: no engine, no ROS), interleaved too. One query at
  a time, the edge node's answer needs the direct call plus at least the echo's round trip, one after the
  other: (direct + echo) / direct is the least ratio it can have. With 8 in flight the two costs added, as if
  nothing overlapped, 1 / (1/echo + 1/direct), is printed as an estimate, not a bound (the broker, the
  application and the simulation are other processes, which overlap on two cores);
* bus messages per goto action (1 invoke + one feedback per state change), vs the reference's 2.

The robot is the simulated RB-1 (examples/robotnik_rb1/sim/ros2.py) in its own process; the edge node (engine,
MQTT client, rclpy node) and the application (a second MQTT client) are in this process.
Needs the ROS 2 extra and mosquitto. Run: `.venv/bin/python bench/edge_node_ros2.py [--runs N]`.
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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from runtime_bus import Replies, latency, model, mosquitto  # noqa: E402

from td2adaptor.runtime import Message, RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.bus.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.bus.security import parse_broker_url  # noqa: E402
from td2adaptor.runtime.ros.genport import GeneratedPort  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import EXAMPLE, Process, generate_rclpy  # noqa: E402

NS = "rb1_edge_bench"
NS2 = "rb1_edge_bench_b"  # the second robot of the concurrency figures
ROOT = f"td2adaptor/{NS}/GoToComponent"
ECHO = "echo"  # the first topic level of the echo's requests and answers
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}]}}
FLOOD = 1000
CONCURRENT = 8  # requests in flight
ROUNDS = 5  # interleaved rounds of the concurrency figures (median of each side)
PER_ROUND = 800  # calls per round and side
#: (component, its query) of the RB-1's procedures, and a run payload to have a mission to query
PROCEDURES = {
    "GoToComponent": ("gotoQuery", "gotoRun", GOAL),
    "PickComponent": ("pickQuery", "pickRun", {"procedure": {"pick_frame_id": "shelf"}}),
    "PlaceComponent": ("placeQuery", "placeRun", {"procedure": {"pick_frame_id": "shelf"}}),
}
#: a procedure's query -> its run action, whose topics carry the query's answer
RUN_OF_QUERY = {query: run_action for query, run_action, _payload in PROCEDURES.values()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=300)
    parser.add_argument("--app", metavar="URL", help=argparse.SUPPRESS)  # the application process (see AppProcess)
    parser.add_argument("--root", default="td2adaptor", help=argparse.SUPPRESS)  # its requests' first topic level
    args = parser.parse_args()
    if args.app:
        app_process(args.app, args.root)
        return
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
        [
            *(sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "0.2"),
            *("--namespace", NS, "--namespace", NS2),
        ],
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
    port2 = GeneratedPort(m, adaptor, NS2, distro="ros2", node=node, timeout=5.0, wait_timeout=20.0)
    lanes = missions(adaptor, node)
    time.sleep(0.4)  # finished
    mid = next(lane.mission for lane in lanes if (lane.robot, lane.component) == (NS, "GoToComponent"))
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {runs} runs, flood of {FLOOD}")
    with mosquitto() as url:
        config = RuntimeConfig(robot=NS, bus=url, poll_period=0.01, property_period=0, call_timeout=5.0)
        engine = serve(m, port, config)
        config2 = RuntimeConfig(robot=NS2, bus=url, poll_period=0.01, property_period=0, call_timeout=5.0)
        engine2 = serve(m, port2, config2)
        replies = Replies()
        app = MqttBus(parse_broker_url(url), client_id="edge-bench-app", clean_start=True)
        app.subscribe(f"{ROOT}/gotoRun/+", replies)
        app.subscribe(f"{ECHO}/{ROOT}/gotoRun/+", replies)
        pipeline = Pipeline(app, lanes)
        for robot in (NS, NS2):
            for component, (_query, run_action, _payload) in PROCEDURES.items():
                app.subscribe(f"td2adaptor/{robot}/{component}/{run_action}/+", pipeline)
        app.connect()
        echo = Echo(url)

        def send(topic: str, event: dict[str, Any]) -> None:
            app.publish(topic, json.dumps(event).encode())

        def answered_in(root: str, corr: str) -> float:
            """Seconds from a gotoQuery event under `root` to its answer."""
            t0 = time.perf_counter()
            send(f"{root}/gotoQuery", {"correlation": corr, "mission": mid})
            replies.wait(lambda: corr in replies.by_corr)
            return time.perf_counter() - t0

        direct_q, port_q, event_q, echo_q = [], [], [], []
        try:
            for i in range(runs):  # interleaved: the three see the same machine state
                t0 = time.perf_counter()
                goto.call_gotoQuery(mission_id=mid)
                direct_q.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                port.query("GoToComponent", "gotoQuery", mid, 5.0)
                port_q.append(time.perf_counter() - t0)
                event_q.append(answered_in(ROOT, f"q{i}"))
                echo_q.append(answered_in(f"{ECHO}/{ROOT}", f"e{i}"))
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
            direct_8, edge_8, apart_8, echo_8 = [], [], [], []
            pipeline.round(CONCURRENT * 10)  # warm-up
            outside = AppProcess(url, lanes)
            outside.round(CONCURRENT * 10)
            echo_outside = AppProcess(url, lanes, f"{ECHO}/td2adaptor")
            echo_outside.round(CONCURRENT * 10)
            for _ in range(ROUNDS):  # interleaved rounds: all see the same machine state
                direct_8.append(concurrent_direct(lanes, PER_ROUND))
                edge_8.append(pipeline.round(PER_ROUND))
                apart_8.append(outside.round(PER_ROUND))
                echo_8.append(echo_outside.round(PER_ROUND))
            outside.close()
            echo_outside.close()
        finally:
            engine.stop()
            engine2.stop()
            app.close()
            echo.close()
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
    print("issue 17 (edge node vs direct rclpy calls, same run):")
    for name, q in (("median", 50), ("p99", 99)):
        edge_ms, direct_ms = percentile(event_q, q) * 1000, percentile(direct_q, q) * 1000
        goal = "   target <= 1.3x" if name == "median" else ""
        print(
            f"  {'query latency ' + name:<42} {edge_ms:8.3f} ms   {'call_gotoQuery':<20} {direct_ms:7.3f} ms   "
            f"ratio {edge_ms / direct_ms:5.2f}x{goal}"
        )
    echo_ms, direct_ms = med(echo_q) * 1000, med(direct_q) * 1000
    print(
        f"  {'query median, MQTT echo alone':<42} {echo_ms:8.3f} ms   the least ratio any broker-borne answer "
        f"can have: (direct + echo) / direct = {(direct_ms + echo_ms) / direct_ms:4.2f}x"
    )
    spread = f"{len({lane.robot for lane in lanes})} robots x {len({lane.component for lane in lanes})} components"
    for where, rates in (("app in its own process", apart_8), ("app in this process", edge_8)):
        label = f"  {CONCURRENT} in flight ({spread}), {where}"
        print(
            f"{label:<60} {med(rates):6.0f} /s   {'8 threads, call_X':<18} {med(direct_8):6.0f} /s   "
            f"ratio {med(rates) / med(direct_8):5.2f}x   target >= 0.8x"
        )
    e8, d8 = med(echo_8), med(direct_8)
    label = f"  {CONCURRENT} in flight, MQTT echo alone, app in its own process"
    print(
        f"{label:<60} {e8:6.0f} /s   the two costs added, nothing overlapping: "
        f"1 / (1/echo + 1/direct) = {1 / (1 / e8 + 1 / d8):4.0f} /s, {e8 / (e8 + d8):4.2f}x"
    )
    print(f"  ({ROUNDS} interleaved rounds of {PER_ROUND} calls, medians; the edge node's engines are in this process)")


def percentile(values: list[float], q: int) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q / 100 * (len(ordered) - 1)))]


@dataclass
class Lane:
    """One stream of requests: a component of a robot, the direct client, and the mission it queries."""

    robot: str
    component: str
    query: str
    client: Any
    mission: int


def missions(adaptor: Any, node: Any) -> list[Lane]:
    """Start one mission per procedure component and robot (to have a mission to query); CONCURRENT lanes,
    round-robin over the (robot, component) pairs."""
    pairs = []
    for robot in (NS, NS2):
        for component, (query, run_action, payload) in PROCEDURES.items():
            client = getattr(adaptor, component)(node, robot, timeout=5.0, wait_timeout=20.0)
            construct = getattr(client, f"construct_{run_action}_Msg")
            started = getattr(client, f"call_{run_action}")(construct(**payload))
            pairs.append((robot, component, query, client, int(started.mission_id)))
    return [Lane(*pairs[i % len(pairs)]) for i in range(CONCURRENT)]


def concurrent_direct(lanes: list[Lane], total: int) -> float:
    """Calls per second of len(lanes) threads calling their lane's query directly, `total` calls in all."""
    per = total // len(lanes)
    go = threading.Barrier(len(lanes) + 1)

    def work(lane: Lane) -> None:
        call = getattr(lane.client, f"call_{lane.query}")
        go.wait()
        for _ in range(per):
            call(mission_id=lane.mission)

    threads = [threading.Thread(target=work, args=(lane,)) for lane in lanes]
    for thread in threads:
        thread.start()
    go.wait()
    t0 = time.perf_counter()
    for thread in threads:
        thread.join()
    return per * len(lanes) / (time.perf_counter() - t0)


class AppProcess:
    """The pipelining application in a process of its own (the edge node's process then does only its own
    work, as `td2adaptor run` would): `round(total)` as Pipeline's, over stdin/stdout."""

    def __init__(self, url: str, lanes: list[Lane], root: str = "td2adaptor") -> None:
        spec = [[lane.robot, lane.component, lane.query, lane.mission] for lane in lanes]
        environ = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--app", url, "--root", root],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env=environ,
        )
        self._say(json.dumps(spec))
        assert self._hear() == "ready"

    def _say(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def _hear(self) -> str:
        assert self.proc.stdout is not None
        return self.proc.stdout.readline().strip()

    def round(self, total: int) -> float:
        self._say(str(total))
        return float(self._hear())

    def close(self) -> None:
        self._say("")
        self.proc.wait(30)


def app_process(url: str, root: str) -> None:
    """The application process of AppProcess: lanes on the first stdin line, then one round per line."""
    lanes = [Lane(robot, component, query, None, mission) for robot, component, query, mission in json.loads(input())]
    app = MqttBus(parse_broker_url(url), client_id=f"edge-bench-app-process-{root}", clean_start=True)
    pipeline = Pipeline(app, lanes, root)
    for lane in lanes:
        app.subscribe(f"{root}/{lane.robot}/{lane.component}/{RUN_OF_QUERY[lane.query]}/+", pipeline)
    app.connect()
    print("ready", flush=True)
    for line in sys.stdin:
        if not line.strip():
            break
        print(pipeline.round(int(line)), flush=True)
    app.close()


class Echo:
    """The floor of an answer over the broker: an MQTT client (the edge node's kind, in this process as its
    engines are) that publishes every request on `echo/td2adaptor/<robot>/<component>/<query>` back, as it
    came, on the run action's answer topic (`.../<run>/state`), without reading it."""

    def __init__(self, url: str) -> None:
        self.bus = MqttBus(parse_broker_url(url), client_id="edge-bench-echo", clean_start=True)
        self.bus.subscribe(f"{ECHO}/td2adaptor/+/+/+", self)
        self.bus.connect()

    def __call__(self, msg: Message) -> None:
        head, query = msg.topic.rsplit("/", 1)
        run_action = RUN_OF_QUERY.get(query)
        if run_action is not None:
            self.bus.publish(f"{head}/{run_action}/state", msg.payload)

    def close(self) -> None:
        self.bus.close()


class Pipeline:
    """Keeps one query event in flight per lane: each answer (in the app's MQTT thread) sends the lane's next.
    `root`: the requests' first topic level (the echo's, or the edge node's)."""

    def __init__(self, app: MqttBus, lanes: list[Lane], root: str = "td2adaptor") -> None:
        self.app = app
        self.lanes = lanes
        self.root = root
        self.done = threading.Event()
        self.left = 0
        self.sent = 0
        self.generation = 0
        self.lock = threading.Lock()

    def _send(self, lane: int) -> None:
        spec = self.lanes[lane]
        event = {"correlation": f"p{self.generation}-{lane}-{self.sent}", "mission": spec.mission}
        self.app.publish(f"{self.root}/{spec.robot}/{spec.component}/{spec.query}", json.dumps(event).encode())

    def __call__(self, msg: Message) -> None:
        corr = json.loads(msg.payload).get("correlation", "")
        parts = corr.split("-")
        if len(parts) != 3 or parts[0] != f"p{self.generation}":
            return
        with self.lock:
            self.left -= 1
            if self.left == 0:
                self.done.set()
            more = self.sent < self.total
            if more:
                self.sent += 1
        if more:
            self._send(int(parts[1]))

    def round(self, total: int) -> float:
        """Calls per second with len(lanes) in flight, `total` answers in all."""
        with self.lock:
            self.generation += 1
            self.total, self.left, self.sent = total, total, len(self.lanes)
            self.done.clear()
        t0 = time.perf_counter()
        for lane in range(len(self.lanes)):
            self._send(lane)
        assert self.done.wait(120), "answers missing"
        return total / (time.perf_counter() - t0)


if __name__ == "__main__":
    main()
