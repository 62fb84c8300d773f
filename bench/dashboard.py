"""The dashboard (issue 33): how long a robot's published value takes to be on the page's screen, measured in
the page (headless Chromium: the value's `stamp`, the publisher's wall clock, against the animation frame that
drew it), with 1 and with 100 robots each publishing a pose at 10 Hz, and the dashboard server's CPU.

The robots are a stand-in publisher (one paho client, QoS 0 as a sensor stream is sent): each robot's retained
TD (one observable `odometry` property: x, y, theta, stamp) and online status, then its values spread evenly
over each 100 ms; the dashboard is the real `td2adaptor dashboard` process on a real mosquitto, and the page
watches robot b0 (its values, the fleet list and the map of all of them).
"""

from __future__ import annotations

import json
import math
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import paho.mqtt.client as mqtt  # noqa: E402
from paho.mqtt.enums import CallbackAPIVersion  # noqa: E402

RATE = 10.0  # values per robot and second
SECONDS = 10.0  # measured, after WARMUP
WARMUP = 3.0


def td(robot: str, broker: str) -> dict[str, Any]:
    topic = f"td2adaptor/{robot}/wot-thing/Odom/odometry"
    number = {"type": "number"}
    return {
        "@context": "https://www.w3.org/2022/wot/td/v1.1",
        "title": f"Bench robot {robot}",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "properties": {
            "odometry": {
                "type": "object",
                "properties": {"x": number, "y": number, "theta": number, "stamp": number},
                "observable": True,
                "forms": [{"href": f"{broker}/{topic}", "op": ["readproperty", "observeproperty"], "mqv:topic": topic}],
            }
        },
    }


class Publisher:
    """`count` robots: retained TD and status, then odometry at RATE each until `stop`."""

    def __init__(self, broker: Any, count: int) -> None:
        self.count = count
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"bench-robots-{count}")
        self.client.connect("127.0.0.1", broker.port)
        self.client.loop_start()
        self.sent = 0
        for i in range(count):
            robot = f"b{i}"
            self.client.publish(f"td2adaptor/{robot}/td", json.dumps(td(robot, broker.url)), qos=1, retain=True)
            status = {"type": "status", "robot": robot, "payload": {"state": "online", "thing": "bench"}}
            self.client.publish(f"td2adaptor/{robot}/status", json.dumps(status), qos=1, retain=True)
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)

    def run(self) -> None:
        period = 1.0 / RATE
        start = time.monotonic()
        tick = 0
        while not self.stopping.is_set():
            for i in range(self.count):
                due = start + tick * period + i * period / self.count
                delay = due - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                angle = (tick / RATE + i) * 0.3
                value = {"x": 5 * math.cos(angle) + i % 10, "y": 5 * math.sin(angle) + i // 10, "theta": angle}
                value["stamp"] = time.time() * 1000.0
                self.client.publish(f"td2adaptor/b{i}/wot-thing/Odom/odometry", json.dumps(value), qos=0)
                self.sent += 1
            tick += 1

    def close(self) -> None:
        self.stopping.set()
        self.thread.join(5)
        for i in range(self.count):  # leave the broker as found: no retained TD
            self.client.publish(f"td2adaptor/b{i}/td", b"", qos=1, retain=True)
        self.client.loop_stop()
        self.client.disconnect()


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(count: int) -> None:
    from tests.dashboard.harness import chromium, css, dashboard, wait
    from tests.runtime.broker import Mosquitto

    with tempfile.TemporaryDirectory() as tmp:
        broker = Mosquitto(Path(tmp) / "broker")
        broker.start()
        robots = Publisher(broker, count)
        try:
            with dashboard(broker.url) as dash, chromium() as driver:
                driver.get(f"{dash.url}#/robot/b0")
                wait(driver, lambda d: len(css(d, "#robots li")) == count, 60, "the robots listed")
                robots.thread.start()
                wait(driver, lambda d: css(d, '[data-prop="odometry"] [data-pointer="/stamp"]'), 30, "values")
                time.sleep(WARMUP)
                driver.execute_script("window.dashboardProbe.paints.length = 0")
                sent, cpu, wall = robots.sent, cpu_seconds(dash.proc.pid), time.monotonic()
                time.sleep(SECONDS)
                paints = driver.execute_script("return window.dashboardProbe.paints")
                cpu, wall = cpu_seconds(dash.proc.pid) - cpu, time.monotonic() - wall
                sent = robots.sent - sent
        finally:
            robots.close()
            broker.stop()
    latencies = [p["paint"] - p["stamp"] for p in paints if p["name"] == "odometry" and p["stamp"] is not None]
    latencies.sort()
    p95 = latencies[int(0.95 * (len(latencies) - 1))]
    print(
        f"{count:3d} robot(s) x {RATE:g} Hz ({sent / wall:.0f} values/s on the bus): b0 on screen "
        f"{len(latencies) / wall:.1f}/s, latency median {statistics.median(latencies):.1f} ms, p95 {p95:.1f} ms, "
        f"max {latencies[-1]:.1f} ms; dashboard server CPU {100 * cpu / wall:.0f} % of a core"
    )


def main() -> None:
    from tests.dashboard.harness import CHROMEDRIVER, CHROMIUM

    if CHROMIUM is None or CHROMEDRIVER is None:
        print("skipped: headless Chromium is not installed (.ci/setup-browser.sh)")
        return
    for count in (1, 100):
        measure(count)


if __name__ == "__main__":
    main()
