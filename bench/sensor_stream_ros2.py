"""Sensor streams as property events (issue 17). Every figure is printed next to a baseline measured in the same run.

Per robot, a plain rclpy publisher process sends `odom` (nav_msgs/Odometry) at 100 Hz and `scan`
(sensor_msgs/LaserScan, 720 ranges, best effort) at 10 Hz: 110 messages per second. The edge node is one
`td2adaptor run` process serving N such robots (a fleet file) from a TD with those two properties (the `odom`
and `scan` properties of examples/nav_base/td.json), publishing property events on a real mosquitto that a
counting MQTT client in this process subscribes to.

Modes (docs/fleet.md):

* `full rate`: `property_mode: message`, every message one property event (`mode` column `msg`), on the
  generated package's SingleThreadedExecutor;
* `throttled`: `property_mode: message` with `property_interval` 0.1 s (at most 10 events per second per
  property, the latest message);
* `sampled`: the sampling mode, `property_period` 0.005 s (twice as fast as odom comes) and the default 1 s.

Full rate is measured at each `property_qos` of `--qos` (default 1 and 0: property events acknowledged or at
most once).

The robots are increased until the edge-node process saturates (its events per second stop growing); the
maximum is compared with the target (>= 2,000 property events per second per process).

Baseline (the floor): the same messages received by a plain rclpy subscriber (SingleThreadedExecutor, as
`rclpy.spin` and the generated packages use, and a callback that counts) in one process: messages per second and
CPU per message; and the same subscriber on rclpy's experimental EventsExecutor (C++), to show what of the
floor is the Python executor.

Needs the ROS 2 extra and mosquitto. Run: `.venv/bin/python bench/sensor_stream_ros2.py [--robots 5,10,20,40]`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

NAV_BASE = REPO / "examples" / "nav_base"
PREFIX = "stream"
ODOM_HZ, SCAN_HZ, BEAMS = 100, 10, 720
PER_ROBOT = ODOM_HZ + SCAN_HZ
TICK = os.sysconf("SC_CLK_TCK")
TARGET = 2000.0


def emit(event: str, **fields: Any) -> None:
    print(json.dumps({"event": event, **fields}), flush=True)


def cpu_seconds(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / TICK


def scan_qos() -> Any:
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)


# -- child processes: the sensors, and the floor --------------------------------------------------------------


def publish(robots: int) -> None:
    """The robots' sensors: odom at 100 Hz and a 720-range scan at 10 Hz per robot, from one rclpy process;
    a `published` line with the counts every second."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from sensor_msgs.msg import LaserScan

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("stream_sensors", context=context)
    names = [f"{PREFIX}_{i}" for i in range(robots)]
    odom_pubs = [node.create_publisher(Odometry, f"/{ns}/odom", 10) for ns in names]
    scan_pubs = [node.create_publisher(LaserScan, f"/{ns}/scan", scan_qos()) for ns in names]
    odom = Odometry()
    odom.header.frame_id, odom.child_frame_id = "odom", "base_link"
    odom.pose.pose.orientation.w = 1.0
    odom.twist.twist.linear.x = 0.5
    scan = LaserScan()
    scan.header.frame_id = "laser"
    scan.angle_min, scan.angle_max = -math.pi, math.pi
    scan.angle_increment = 2 * math.pi / BEAMS
    scan.range_min, scan.range_max = 0.1, 30.0
    ranges = [2.0 + math.sin(i / 20) for i in range(BEAMS)]
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    emit("ready", robots=robots)
    time.sleep(1.0)  # let the subscribers match
    odoms = scans = 0
    start = time.monotonic()
    k = 0
    while not stop.is_set():
        delay = start + k / ODOM_HZ - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        stamp = node.get_clock().now().to_msg()
        odom.header.stamp = stamp
        odom.pose.pose.position.x = k * 0.005
        for pub in odom_pubs:
            pub.publish(odom)
        odoms += len(odom_pubs)
        if k % (ODOM_HZ // SCAN_HZ) == 0:
            scan.header.stamp = stamp
            scan.ranges = [r + 0.001 * (k % 7) for r in ranges]
            for pub in scan_pubs:
                pub.publish(scan)
            scans += len(scan_pubs)
        k += 1
        if k % ODOM_HZ == 0:
            emit("published", odom=odoms, scan=scans, t=time.monotonic())
    node.destroy_node()
    rclpy.shutdown(context=context)


def floor(robots: int, kind: str) -> None:
    """The baseline: a plain rclpy subscriber of every robot's odom and scan that counts what it receives, spun
    by rclpy's SingleThreadedExecutor (`single`, what the generated packages use) or its experimental
    EventsExecutor (`events`, in C++)."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import LaserScan

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("stream_floor", context=context)
    count = [0]

    def on_message(_msg: Any) -> None:
        count[0] += 1

    for i in range(robots):
        node.create_subscription(Odometry, f"/{PREFIX}_{i}/odom", on_message, 10)
        node.create_subscription(LaserScan, f"/{PREFIX}_{i}/scan", on_message, scan_qos())
    node.create_timer(1.0, lambda: emit("received", n=count[0], t=time.monotonic()))
    executor: Any
    if kind == "events":
        from rclpy.experimental import EventsExecutor

        executor = EventsExecutor(context=context)
    else:
        executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    emit("ready", robots=robots)
    while not stop.is_set():
        executor.spin_once(timeout_sec=0.2)
    node.destroy_node()
    rclpy.shutdown(context=context)


# -- the bench ------------------------------------------------------------------------------------------------


class Latest:
    """The last line of each kind a child printed (its cumulative counts)."""

    def __init__(self, proc: Any) -> None:
        self.proc = proc

    def last(self, kind: str, timeout: float = 5.0) -> dict[str, Any]:
        self.proc.wait_for(lambda e: e.get("event") == kind, timeout)
        while not self.proc.events.empty():
            self.proc.seen.append(self.proc.events.get())
        return next(e for e in reversed(self.proc.seen) if e.get("event") == kind)

    def next(self, kind: str, timeout: float = 5.0) -> dict[str, Any]:
        before = len(self.proc.seen)
        return self.proc.wait_for(lambda e: e.get("event") == kind and self.proc.seen.index(e) >= before, timeout)


class Counter:
    """Property events arriving on the broker, counted (nothing parsed), from one MQTT client."""

    def __init__(self, url: str) -> None:
        from td2adaptor.runtime.bus.mqttbus import MqttBus
        from td2adaptor.runtime.bus.security import parse_broker_url

        self.n = 0
        self.online: set[str] = set()
        self.lock = threading.Lock()
        self.bus = MqttBus(  # retained flag on the values a subscription finds only, not on the live events
            parse_broker_url(url), client_id=f"stream-bench-{os.getpid()}", clean_start=True, retain_as_published=False
        )
        self.bus.subscribe("td2adaptor/+/BaseComponent/odom", self._count)
        self.bus.subscribe("td2adaptor/+/LaserComponent/scan", self._count)
        self.bus.subscribe("td2adaptor/+/status", self._status)
        self.bus.connect()

    def _count(self, msg: Any) -> None:
        if not msg.retain:
            self.n += 1  # one paho thread calls this

    def _status(self, msg: Any) -> None:
        if msg.payload and b'"online"' in msg.payload:
            with self.lock:
                self.online.add(msg.topic.split("/")[1])

    def close(self) -> None:
        self.bus.close()


class NotOnline(Exception):
    """A step whose edge node did not have every robot online in time: said in words, the other steps go on."""


@dataclass
class Mode:
    """How the edge node relays the properties: `msg` (per message, `interval` the property_interval) or `sample`
    (`interval` the property_period), on the `single` or `events` executor, published at MQTT QoS `qos`
    (property_qos)."""

    kind: str
    interval: float
    executor: str = "single"
    qos: int = 1

    def __str__(self) -> str:
        return f"{self.kind} {self.interval:g}s {self.executor} qos{self.qos}"


@dataclass
class Step:
    robots: int
    period: Mode
    sent: float  # sensor messages per second published
    events: float  # property events per second
    cpu: float  # edge node, % of one core
    floor_rate: float = 0.0
    floor_cpu: float = 0.0
    events_floor_rate: float = 0.0  # the same subscriber on rclpy's EventsExecutor
    events_floor_cpu: float = 0.0


def stream_td(work: Path) -> Path:
    """examples/nav_base/td.json with only its odom and scan properties."""
    td = json.loads((NAV_BASE / "td.json").read_text(encoding="utf-8"))
    td["title"] = "Stream Base"
    td["actions"] = {}
    td["properties"] = {k: v for k, v in td["properties"].items() if k in ("odom", "scan")}
    path = work / "stream.td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    return path


def run_edge(work: Path, td: Path, src: Path, url: str, robots: int, period: Mode, environ: dict[str, str]) -> Any:
    config = work / f"edge-{robots}-{period.kind}-{period.interval:g}-{period.executor}-{period.qos}.yaml"
    if period.kind == "msg":
        lines = ["property_mode: message", f"property_interval: {period.interval}"]
    else:
        lines = [f"property_period: {period.interval}"]
    lines.append(f"property_qos: {period.qos}")
    lines += [f"bus: {url}", "state_dir: ''", "robots:"]
    lines += [f"  - robot: {PREFIX}_{i}" for i in range(robots)]
    config.write_text("\n".join(lines) + "\n", encoding="utf-8")
    argv = [sys.executable, "-m", "td2adaptor", "run", str(td), "-I", str(NAV_BASE / "interfaces")]
    argv += ["--package-path", str(src), "--config", str(config), "--log-level", "warning"]
    log = config.with_suffix(".log").open("wb")
    proc = subprocess.Popen(argv, env=environ, stdout=log, stderr=subprocess.STDOUT, cwd=REPO)
    log.close()
    return proc


def stop(proc: Any) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


def measure(ctx: dict[str, Any], counter: Counter, robots: int, period: Mode, window: float, with_floor: bool) -> Step:
    from tests.ros2.common import Process

    me = Path(__file__).resolve()
    environ = ctx["env"]
    sensors = Process([sys.executable, str(me), "--publisher", str(robots)], environ)
    pub = Latest(sensors)
    try:
        sensors.wait_for(lambda e: e.get("event") == "ready", 60)
        floors: dict[str, tuple[float, float]] = {}
        for kind in ("single", "events") if with_floor else ():
            sub = Process([sys.executable, str(me), "--floor", str(robots), "--floor-executor", kind], environ)
            try:
                got = Latest(sub)
                sub.wait_for(lambda e: e.get("event") == "ready", 60)
                time.sleep(2.0)
                a, c0, t0 = got.last("received"), cpu_seconds(sub.proc.pid), time.monotonic()
                time.sleep(window)
                c1, t1 = cpu_seconds(sub.proc.pid), time.monotonic()
                b = got.next("received")
                # the count's window is the child's (its lines' times), the CPU's this process's clock
                floors[kind] = ((b["n"] - a["n"]) / (b["t"] - a["t"]), 100 * (c1 - c0) / (t1 - t0))
            finally:
                sub.stop()
        with counter.lock:
            counter.online.clear()
        edge = run_edge(ctx["work"], ctx["td"], ctx["src"], ctx["url"], robots, period, environ)
        try:
            deadline = time.monotonic() + 120
            while len(counter.online) < robots and time.monotonic() < deadline and edge.poll() is None:
                time.sleep(0.1)
            if len(counter.online) < robots:
                raise NotOnline(
                    f"{robots} robots, {period}: not measured: {len(counter.online)} of {robots} robots online after "
                    f"120 s (edge node {'still starting' if edge.poll() is None else f'exit {edge.poll()}'}; its "
                    f"log in {ctx['work']})"
                )
            time.sleep(3.0)  # discovery, first messages
            a, n0, c0, t0 = pub.last("published"), counter.n, cpu_seconds(edge.pid), time.monotonic()
            time.sleep(window)
            b, n1, c1, t1 = pub.next("published"), counter.n, cpu_seconds(edge.pid), time.monotonic()
        finally:
            stop(edge)
    finally:
        sensors.stop()
    sent = (b["odom"] + b["scan"] - a["odom"] - a["scan"]) / (b["t"] - a["t"])
    step = Step(robots, period, sent, (n1 - n0) / (t1 - t0), 100 * (c1 - c0) / (t1 - t0))
    step.floor_rate, step.floor_cpu = floors.get("single", (0.0, 0.0))
    step.events_floor_rate, step.events_floor_cpu = floors.get("events", (0.0, 0.0))
    return step


def report(steps: Sequence[Step]) -> None:
    print(
        f"{'robots':>6} {'mode':>18} {'sent msg/s':>11} {'events/s':>9} {'relayed':>8} {'edge CPU':>9} "
        f"{'CPU/event':>10}   {'floor msg/s':>11} {'floor CPU':>9} {'CPU/msg':>9}   {'events/floor':>12}   "
        f"{'EventsExecutor floor: msg/s':>27} {'CPU':>6} {'CPU/msg':>9}"
    )
    for s in steps:
        per_event = s.cpu / 100 / s.events * 1e6 if s.events else float("nan")
        floor = ""
        if s.floor_rate:
            per_msg = s.floor_cpu / 100 / s.floor_rate * 1e6
            floor = f"{s.floor_rate:11.0f} {s.floor_cpu:8.1f}% {per_msg:7.1f}us   {s.events / s.floor_rate:12.2f}"
        if s.events_floor_rate:
            per_msg = s.events_floor_cpu / 100 / s.events_floor_rate * 1e6
            floor += f"   {s.events_floor_rate:27.0f} {s.events_floor_cpu:5.1f}% {per_msg:7.1f}us"
        print(
            f"{s.robots:6d} {str(s.period):>18} {s.sent:11.0f} {s.events:9.0f} {s.events / s.sent:8.2f} "
            f"{s.cpu:8.1f}% {per_event:8.1f}us   {floor}"
        )
    full = [s for s in steps if s.period.kind == "msg" and s.period.interval == 0]
    for qos in sorted({s.period.qos for s in full}):
        top = max((s for s in full if s.period.qos == qos), key=lambda s: s.events)
        print(f"full rate at property_qos {qos}: at most {top.events:.0f} events/s ({top.robots} robots)")
    best = max(full or steps, key=lambda s: s.events)
    met = "met" if best.events >= TARGET else "NOT met"
    print(
        f"max property events/s of one edge-node process: {best.events:.0f} ({best.robots} robots, "
        f"{best.cpu:.0f}% of a core, {best.period})   target >= {TARGET:.0f}/s: {met}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", default="1,5,10,20,40", help="robot counts to step through (comma-separated)")
    parser.add_argument("--window", type=float, default=5.0, help="seconds of each measurement")
    parser.add_argument("--qos", default="1,0", help="property_qos values to step through (comma-separated)")
    parser.add_argument("--executors", default="single", help=argparse.SUPPRESS)
    parser.add_argument("--publisher", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--floor", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--floor-executor", default="single", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publisher:
        publish(args.publisher)
        return
    if args.floor:
        floor(args.floor, args.floor_executor)
        return
    from tests.ros2 import env

    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    if shutil.which("mosquitto") is None and not Path("/usr/sbin/mosquitto").exists():
        print("mosquitto not installed: skipped")
        return
    from runtime_bus import mosquitto

    from tests.ros2.common import build_rclpy

    env.isolate()
    work = Path(tempfile.mkdtemp(prefix="td2adaptor-bench-stream-"))
    td = stream_td(work)
    _, src = build_rclpy(td, work / "src", interfaces=NAV_BASE / "interfaces")
    counts = [int(n) for n in args.robots.split(",")]
    print(
        f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {os.cpu_count()} cores, per robot odom "
        f"{ODOM_HZ} Hz + scan of {BEAMS} ranges {SCAN_HZ} Hz = {PER_ROBOT} msg/s, {args.window:g} s windows"
    )
    steps: list[Step] = []
    failed: list[str] = []  # the steps not measured, in words
    with mosquitto() as url:
        counter = Counter(url)
        ctx = {"work": work, "td": td, "src": src, "url": url, "env": env.child_env([])}
        try:
            for qos in (int(q) for q in args.qos.split(",")):
                for executor in args.executors.split(","):
                    mode = Mode("msg", 0.0, executor, qos)
                    for n in counts:
                        first = executor == "single" and qos == int(args.qos.split(",")[0])
                        try:
                            steps.append(measure(ctx, counter, n, mode, args.window, with_floor=first))
                        except NotOnline as exc:
                            failed.append(str(exc))
                            break
                        if steps[-1].events < 0.95 * steps[-1].sent:
                            break  # saturated: it no longer relays every message
            top = max(steps, key=lambda s: s.events)
            for mode in (
                Mode("msg", 0.1, top.period.executor, top.period.qos),
                Mode("sample", 0.005),
                Mode("sample", 1.0),
            ):
                try:
                    steps.append(measure(ctx, counter, top.robots, mode, args.window, with_floor=False))
                except NotOnline as exc:
                    failed.append(str(exc))
        finally:
            counter.close()
    report(steps)
    for line in failed:
        print(line)
    if failed:
        sys.exit(1)  # the logs stay for a look
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
