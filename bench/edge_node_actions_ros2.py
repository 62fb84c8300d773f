"""Edge node serving a ROS 2 action (issue 12). Every figure is printed next to a baseline measured in the same run.

* latency: invoke event → goal → first feedback event, and → terminal event, over a real mosquitto, vs a
  hand-written rclpy ActionClient sending the same goal from this process (send → first feedback callback,
  send → result) (target: overhead <= 2 ms median). The edge node is measured twice: with the default
  `goal_feedback_grace` (ROS 2: 10 ms of waiting after the result for feedback that trails it, a floor on the
  terminal event's overhead) and with grace 0 (the terminal event at once; a trailing message is not reported);
* throughput: feedback events per second the edge node relays from a goal whose server publishes feedback
  every millisecond, vs the feedback messages per second the hand-written client receives from the same goal
  (both graces: how many of the messages each relays).

The robot is tests/runtime/fibo_ros2.py (an rclpy ActionServer of test_msgs/action/Fibonacci) in its own
process; the edge node is `td2adaptor run` in a process of its own, as deployed (both robots in one process, a
fleet file), and the application (an MQTT client) and the baseline client are here. By default the two robots
and the baseline share one action server, so the edge process has two action clients of it: each takes every
status array and feedback message the server publishes (and wakes for the other's responses), which a
deployment, one server per robot, does not pay; `--servers own` gives each of the three its own server
(namespace) in the robot's process. `--edge inline` runs the edge node in this process instead (engine, MQTT
client and rclpy node next to the application and the baseline: all of them then share one interpreter lock).
Needs the ROS 2 extra and mosquitto.
Run: `.venv/bin/python bench/edge_node_actions_ros2.py [--runs N] [--edge process|inline] [--servers shared|own]`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from runtime_bus import Replies, latency, mosquitto  # noqa: E402

import td2adaptor  # noqa: E402
from td2adaptor.backends.registry import load as load_backend  # noqa: E402
from td2adaptor.diagnostics import Diagnostics  # noqa: E402
from td2adaptor.generation.backend import GenOptions  # noqa: E402
from td2adaptor.runtime import RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.bus.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.bus.security import parse_broker_url  # noqa: E402
from td2adaptor.runtime.node.roslink import connect  # noqa: E402
from td2adaptor.runtime.ros.genport import FEEDBACK_GRACE  # noqa: E402
from tests.lowering.test_actions import INTERFACES, action_td  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.common import Process  # noqa: E402
from tests.runtime.fibo_ros2 import FAST  # noqa: E402

NS = "fibo_bench"
#: the two edge-node robots on the bus, both served by the one robot (namespace NS): default grace, grace 0
GRACES = {NS: None, f"{NS}_grace0": 0.0}


def topic(robot: str) -> str:
    return f"td2adaptor/{robot}/MathComponent/fibonacci"


ORDER = 2  # two feedback messages, 50 ms apart, then the result
FLOOD = 2000  # feedback messages of the throughput goal, 1 ms apart


class RawClient:
    """A hand-written rclpy ActionClient (the baseline): times to the first feedback and to the result."""

    def __init__(self, node: Any, namespace: str = NS) -> None:
        from rclpy.action import ActionClient
        from test_msgs.action import Fibonacci

        self.goal_type = Fibonacci.Goal
        self.client = ActionClient(node, Fibonacci, f"/{namespace}/fibonacci")
        assert self.client.wait_for_server(timeout_sec=30), "no action server"

    def run(self, order: int) -> tuple[float, float, int]:
        """(seconds to the first feedback, seconds to the result, feedback messages received)."""
        first = threading.Event()
        done = threading.Event()
        count = [0]
        marks: dict[str, float] = {}

        def on_feedback(_msg: Any) -> None:
            count[0] += 1
            if not first.is_set():
                marks["first"] = time.perf_counter()
                first.set()

        def on_result(_future: Any) -> None:
            marks["result"] = time.perf_counter()
            done.set()

        def on_goal(future: Any) -> None:
            future.result().get_result_async().add_done_callback(on_result)

        t0 = time.perf_counter()
        self.client.send_goal_async(self.goal_type(order=order), feedback_callback=on_feedback).add_done_callback(
            on_goal
        )
        assert done.wait(120), "no result"
        time.sleep(0.02)  # feedback of the same wake-up
        return marks.get("first", marks["result"]) - t0, marks["result"] - t0, count[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument(
        "--edge",
        choices=("process", "inline"),
        default="process",
        help="process: the edge node is `td2adaptor run` in a process of its own, as deployed (default); inline: "
        "it runs in this process, next to the application and the baseline client",
    )
    parser.add_argument(
        "--servers",
        choices=("shared", "own"),
        default="shared",
        help="shared: the baseline and both robots use one action server (default); own: each its own (see above)",
    )
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    env.isolate()
    work = Path(tempfile.mkdtemp(prefix="td2adaptor-bench-actions-"))
    td = work / "td.json"
    td.write_text(json.dumps(action_td()), encoding="utf-8")
    result = td2adaptor.compile(td, interfaces=[INTERFACES])
    assert result.model is not None
    model = result.model
    for rel, data in load_backend("rclpy").generate(model, GenOptions(), Diagnostics()):
        (work / "src" / rel).parent.mkdir(parents=True, exist_ok=True)
        (work / "src" / rel).write_bytes(data)
    own = args.servers == "own"
    spaces = {r: (f"{NS}_{i}" if own else NS) for i, r in enumerate(GRACES)}
    raw_ns = f"{NS}_raw" if own else NS
    served = sorted({raw_ns, *spaces.values()})
    robot = Process([sys.executable, "-m", "tests.runtime.fibo_ros2", *served], env.child_env([]))
    try:
        robot.wait_for(lambda e: e.get("event") == "ready", 30)
        with mosquitto() as url:
            configs = [
                RuntimeConfig(
                    robot=robot,
                    namespace=spaces[robot],
                    bus=url,
                    poll_period=0.5,
                    property_period=0,
                    state_dir="",
                    goal_feedback_grace=grace,
                )
                for robot, grace in GRACES.items()
            ]
            src = work / "src" / model.package_name
            if args.edge == "process":
                graces = {
                    c.robot: FEEDBACK_GRACE["ros2"] if c.goal_feedback_grace is None else c.goal_feedback_grace
                    for c in configs
                }
                with edge_process(td, src, url, graces, work, spaces):
                    run(list, graces, url, args.runs, raw_ns)
            else:
                link = connect(model, model.package_name, configs, ros=2, package_paths=[src])
                try:
                    run(
                        lambda: [serve(model, link.ports[c.robot], c) for c in configs],
                        {c.robot: link.ports[c.robot].feedback_grace for c in configs},
                        url,
                        args.runs,
                        raw_ns,
                    )
                finally:
                    link.close()
    finally:
        robot.stop()


@contextlib.contextmanager
def edge_process(
    td: Path, src: Path, url: str, graces: dict[str, float], work: Path, spaces: dict[str, str]
) -> Iterator[None]:
    """`td2adaptor run` serving the robots of `graces` (one process for both, as a fleet file says; each robot's
    server in its namespace of `spaces`), until both are online on the bus."""
    config = work / "edge.yaml"
    robots = "".join(
        f"  - robot: {robot}\n    namespace: {spaces[robot]}\n    goal_feedback_grace: {grace}\n"
        for robot, grace in graces.items()
    )
    config.write_text(f"bus: {url}\npoll_period: 0.5\nproperty_period: 0\nstate_dir: ''\nrobots:\n{robots}")
    online = Replies()
    watch = MqttBus(parse_broker_url(url), client_id="actions-bench-watch", clean_start=True)
    watch.subscribe("td2adaptor/+/status", online)
    watch.connect()
    cmd = [
        sys.executable,
        "-m",
        "td2adaptor",
        "run",
        str(td),
        "-I",
        str(INTERFACES),
        "--config",
        str(config),
        "--package-path",
        str(src),
    ]
    proc = subprocess.Popen(cmd, env=env.child_env([]), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:

        def up() -> bool:
            states = {e.get("robot"): e["payload"].get("state") for events in online.by_corr.values() for e in events}
            return all(states.get(robot) == "online" for robot in graces) or proc.poll() is not None

        online.wait(up, timeout=120)
        if proc.poll() is not None:
            raise SystemExit(f"td2adaptor run exited: {proc.stderr.read().decode() if proc.stderr else ''}")
        yield
    finally:
        watch.close()
        proc.terminate()
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()


def run(start: Callable[[], list[Any]], graces: dict[str, float], url: str, runs: int, raw_ns: str = NS) -> None:
    """Measure; `start()` starts the edge nodes that run in this process (stopped at the end), if any."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("bench_raw_client", context=context)
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(node)
    spin = threading.Thread(target=executor.spin, daemon=True)
    spin.start()
    engines = start()
    replies = Replies()
    app = MqttBus(parse_broker_url(url), client_id="actions-bench-app", clean_start=True)
    app.subscribe("td2adaptor/+/MathComponent/fibonacci/+", replies)
    app.connect()
    servers = "one action server each" if raw_ns != NS else "one action server for all"
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {runs} runs, flood of {FLOOD}, {servers}")
    robots = list(graces)
    try:
        raw = RawClient(node, raw_ns)
        raw.run(ORDER)  # warm-up: discovery on both sides
        for robot in robots:
            edge(app, replies, robot, f"warm-{robot}", ORDER)
        raw_first: list[float] = []
        raw_end: list[float] = []
        edge_first: dict[str, list[float]] = {r: [] for r in robots}
        edge_end: dict[str, list[float]] = {r: [] for r in robots}
        for i in range(runs):  # interleaved: all see the same machine state
            first, end, _ = raw.run(ORDER)
            raw_first.append(first)
            raw_end.append(end)
            # the robots take turns at going first: the goal sent right after the baseline's comes 2-3 ms later
            # to its first feedback, whichever robot sends it (measured), and that is no robot's own cost
            for robot in robots[i % 2 :] + robots[: i % 2]:
                first, end, _ = edge(app, replies, robot, f"g{i}-{robot}", ORDER)
                edge_first[robot].append(first)
                edge_end[robot].append(end)
        _, raw_time, raw_count = raw.run(FAST + FLOOD)
        flood = {robot: edge(app, replies, robot, f"flood-{robot}", FAST + FLOOD)[1:] for robot in robots}
    finally:
        for engine in engines:
            engine.stop()
        app.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    med = statistics.median
    target = "<= 2 ms"
    for robot in robots:
        grace = f"grace {graces[robot] * 1000:g} ms"
        first_label = f"goal -> 1st feedback event ({grace})"
        latency(first_label, med(edge_first[robot]), "ActionClient", med(raw_first), target)
        latency(f"goal -> terminal event ({grace})", med(edge_end[robot]), "ActionClient", med(raw_end), target)
    for robot in robots:
        edge_time, edge_count = flood[robot]
        label = f"feedback events/s, MQTT (grace {graces[robot] * 1000:g} ms)"
        print(
            f"{label:<44} {edge_count / edge_time:8.0f} /s   {'ActionClient':<20} {raw_count / raw_time:7.0f} /s   "
            f"({edge_count} and {raw_count} of {FLOOD} messages)"
        )


def edge(app: MqttBus, replies: Replies, robot: str, corr: str, order: int) -> tuple[float, float, int]:
    """Through the edge node serving `robot`: (seconds to the first feedback event with a ROS feedback message,
    to the terminal event, feedback events carrying a ROS message)."""
    marks: dict[str, float] = {}

    def seen() -> bool:
        events = replies.by_corr.get(corr, [])
        if "first" not in marks and any("feedback" in e["payload"] for e in events):
            marks["first"] = time.perf_counter()
        return any(e["payload"].get("terminal") for e in events)

    t0 = time.perf_counter()
    app.publish(topic(robot), json.dumps({"correlation": corr, "payload": {"order": order}}).encode())
    replies.wait(seen, timeout=120)
    end = time.perf_counter()
    count = sum(1 for e in replies.by_corr[corr] if "feedback" in e["payload"])
    return marks.get("first", end) - t0, end - t0, count


if __name__ == "__main__":
    main()
