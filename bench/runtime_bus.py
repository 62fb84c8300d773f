"""Event runtime benchmarks (issue 5). Every figure is printed next to a baseline measured in this run.

* latency: query event → robot call → state event, and invoke event → start call → first feedback, over a
  real mosquitto (started here on a free loopback port) and over the in-process bus, vs calling the port
  directly (target: overhead <= 2 ms median over MQTT);
* throughput: query events one engine answers per second, vs direct port calls per second;
* bus messages per action: one goto mission (queued → running → finished), vs the reference edge node's 2
  (one event in, one terminal answer out, no intermediate states).

The robot is the simulated RB-1 core behind `SimPort` (no ROS): what is measured is the runtime itself.
"""

from __future__ import annotations

import getpass
import json
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import td2adaptor  # noqa: E402
from examples.robotnik_rb1.sim.core import RobotSim  # noqa: E402
from td2adaptor.model import Model  # noqa: E402
from td2adaptor.runtime import Bus, LocalBroker, LocalBus, Message, RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.bus.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.bus.security import parse_broker_url  # noqa: E402
from td2adaptor.runtime.ros.simport import SimPort  # noqa: E402

ROBOT = "bench"
ROOT = f"td2adaptor/{ROBOT}/GoToComponent"
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}]}}
RUNS = 300
FLOOD = 2000


def model() -> Model:
    ex = REPO / "examples" / "robotnik_rb1"
    result = td2adaptor.compile(ex / "td.json", interfaces=[ex / "interfaces"])
    assert result.model is not None
    return result.model


@contextmanager
def mosquitto() -> Iterator[str]:
    binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
    with tempfile.TemporaryDirectory() as tmp, socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        s.close()
        conf = Path(tmp) / "m.conf"
        conf.write_text(
            f"listener {port} 127.0.0.1\nallow_anonymous true\nuser {getpass.getuser()}\nlog_dest none\n"
            "max_queued_messages 100000\nset_tcp_nodelay true\n",
            encoding="utf-8",
        )
        proc = subprocess.Popen([binary, "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            for _ in range(500):
                try:
                    socket.create_connection(("127.0.0.1", port), 0.1).close()
                    break
                except OSError:
                    time.sleep(0.01)
            yield f"mqtt://127.0.0.1:{port}"
        finally:
            proc.terminate()
            proc.wait(10)


class Replies:
    """Answers (state and feedback events) by correlation, for an application waiting on them."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.by_corr: dict[str, list[dict[str, Any]]] = {}
        self.count = 0

    def __call__(self, msg: Message) -> None:
        event = json.loads(msg.payload)
        with self.cond:
            self.by_corr.setdefault(event.get("correlation", ""), []).append(event)
            self.count += 1
            self.cond.notify_all()

    def wait(self, predicate: Callable[[], bool], timeout: float = 10) -> None:
        with self.cond:
            if not self.cond.wait_for(predicate, timeout):
                raise TimeoutError("no answer")


def app_bus(kind: str, url: str, broker: LocalBroker) -> Bus:
    if kind == "local":
        return LocalBus(broker, "bench-app")
    return MqttBus(parse_broker_url(url), client_id="bench-app", clean_start=True)


def measure(kind: str, url: str, m: Model) -> dict[str, float]:
    broker = LocalBroker()
    sim = RobotSim(ROBOT, duration=0.0, queue_time=0.0)
    config = RuntimeConfig(robot=ROBOT, bus=url if kind == "mqtt" else "local", poll_period=0.001, property_period=0)
    engine = serve(m, SimPort(m, sim), config, broker=broker)
    replies = Replies()
    app = app_bus(kind, url, broker)
    app.subscribe(f"{ROOT}/gotoRun/+", replies)
    app.connect()

    def send(topic: str, event: dict[str, Any]) -> None:
        app.publish(topic, json.dumps(event).encode())

    query_lat, invoke_lat = [], []
    try:
        send(f"{ROOT}/gotoRun", {"correlation": "warm", "payload": GOAL})
        replies.wait(lambda: any(e["payload"].get("terminal") for e in replies.by_corr.get("warm", [])))
        for i in range(RUNS):
            corr = f"q{i}"
            t0 = time.perf_counter()
            send(f"{ROOT}/gotoQuery", {"correlation": corr})
            replies.wait(lambda c=corr: c in replies.by_corr)  # type: ignore[misc]
            query_lat.append(time.perf_counter() - t0)
        for i in range(RUNS // 3):
            corr = f"g{i}"
            t0 = time.perf_counter()
            send(f"{ROOT}/gotoRun", {"correlation": corr, "payload": GOAL})
            replies.wait(lambda c=corr: c in replies.by_corr)  # type: ignore[misc]
            invoke_lat.append(time.perf_counter() - t0)
            replies.wait(lambda c=corr: any(e["payload"].get("terminal") for e in replies.by_corr[c]))  # type: ignore[misc]
        start = replies.count
        t0 = time.perf_counter()
        for i in range(FLOOD):
            send(f"{ROOT}/gotoQuery", {"correlation": f"f{i}"})
        replies.wait(lambda: replies.count - start >= FLOOD, timeout=120)
        rate = FLOOD / (time.perf_counter() - t0)
    finally:
        engine.stop()
        app.close()
    return {"query": statistics.median(query_lat), "invoke": statistics.median(invoke_lat), "rate": rate}


def direct(m: Model) -> dict[str, float]:
    sim = RobotSim(ROBOT, duration=0.0, queue_time=0.0)
    port = SimPort(m, sim)
    port.start("GoToComponent", "gotoRun", GOAL, 5)
    q, s = [], []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        port.query("GoToComponent", "gotoQuery", -1, 5)
        q.append(time.perf_counter() - t0)
    for _ in range(RUNS):
        t0 = time.perf_counter()
        port.start("GoToComponent", "gotoRun", GOAL, 5)
        s.append(time.perf_counter() - t0)
        sim.components["GoToComponent"].active()  # finishes at once (duration 0)
    t0 = time.perf_counter()
    for _ in range(FLOOD):
        port.query("GoToComponent", "gotoQuery", -1, 5)
    return {"query": statistics.median(q), "invoke": statistics.median(s), "rate": FLOOD / (time.perf_counter() - t0)}


def messages_per_action(m: Model) -> int:
    broker = LocalBroker()
    sim = RobotSim(ROBOT, duration=0.2, queue_time=0.05)
    config = RuntimeConfig(robot=ROBOT, poll_period=0.01, property_period=0)
    engine = serve(m, SimPort(m, sim), config, broker=broker)
    replies = Replies()
    app = LocalBus(broker, "count-app")
    app.subscribe(f"{ROOT}/gotoRun/+", replies)
    app.connect()
    before = broker.published
    app.publish(f"{ROOT}/gotoRun", json.dumps({"correlation": "one", "payload": GOAL}).encode())
    replies.wait(lambda: any(e["payload"].get("terminal") for e in replies.by_corr.get("one", [])))
    count = broker.published - before
    engine.stop()
    app.close()
    return count


def latency(name: str, value: float, base_name: str, base: float, target: str = "") -> None:
    ms = 1000.0
    extra = f"   target {target}" if target else ""
    print(
        f"{name:<44} {value * ms:8.3f} ms   {base_name:<20} {base * ms:7.3f} ms   "
        f"overhead {(value - base) * ms:7.3f} ms{extra}"
    )


def main() -> None:
    print(f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {RUNS} runs, flood of {FLOOD}")
    m = model()
    base = direct(m)
    with mosquitto() as url:
        mqtt = measure("mqtt", url, m)
    local = measure("local", "", m)
    target = "<= 2 ms"
    latency("query event -> state event, MQTT, median", mqtt["query"], "port.query direct", base["query"], target)
    latency("invoke event -> 1st feedback, MQTT, median", mqtt["invoke"], "port.start direct", base["invoke"], target)
    latency("query event -> state event, local bus", local["query"], "port.query direct", base["query"])
    latency("invoke event -> 1st feedback, local bus", local["invoke"], "port.start direct", base["invoke"])
    for label, figures in (("MQTT", mqtt), ("local bus", local)):
        print(
            f"{'query events answered per s, ' + label:<44} {figures['rate']:8.0f} /s   "
            f"{'port.query direct':<20} {base['rate']:7.0f} /s"
        )
    count = messages_per_action(m)
    print(
        f"{'bus messages per goto action':<44} {count:8d}      {'reference edge node':<20} {2:7d}      "
        "(ours: 1 in + queued, running, finished; the reference reported only the end)"
    )


if __name__ == "__main__":
    main()
