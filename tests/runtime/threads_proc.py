"""A fleet of simulated RB-1s in a process of its own, counting that process's threads while its missions run:
`python -m tests.runtime.threads_proc BUS [ROBOTS [goals]]` (BUS: `local`, or a broker URL). Prints one JSON
object.

With `goals`, every robot runs a ROS action goal instead (the Fibonacci action of
tests.lowering.test_actions.action_td, served by simulated action servers, `SimActions`, through the port's
callback protocol as the generated packages' goals are): a third of them each `finished`, `cancelled`,
`timeout`; the cancels are sent, and the timeouts pass, only once every robot's goal is running.

A quarter of the robots' missions each take one path of the procedure state machine to its end: `finished`
(the robot ends it), `cancelled` (a cancel event once it runs), `timeout` (the mission timeout passes; the
robot is asked to cancel it) and `unreachable` (the robot stops answering once it runs). Threads are counted
before any engine, with 10 robots served, with all of them served, every 10 ms while the missions are in
flight, after they all ended, and once every engine stopped: every thread of the process, on MQTT too (one
thread serves every connection, runtime/bus/mqttloop.py; it is the process's, not an engine's, and stays).
"""

from __future__ import annotations

import json
import logging
import os
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import td2adaptor
from td2adaptor.runtime import Engine, RuntimeConfig, serve_fleet
from td2adaptor.runtime.bus.bus import Bus, Message
from td2adaptor.runtime.bus.localbus import LocalBroker, LocalBus
from td2adaptor.runtime.ros.simport import SimActions, SimPort
from tests.lowering.test_actions import INTERFACES, action_td
from tests.runtime.rb1 import GOAL, rb1_model, sim

PATHS = ("finished", "cancelled", "timeout", "unreachable")
GOAL_PATHS = ("finished", "cancelled", "timeout")
FIRST = 10  # robots served before the others
#: the simulated action servers' step between feedback messages, and the goals' orders: long enough for a
#: hundred goals to be running at once on a loaded machine
STEP = 0.1
ORDERS = {"finished": 80, "cancelled": 10**6, "timeout": 10**6}


def counted() -> int:
    """The process's threads, every one the OS knows (paho's, ROS's and the runtime's alike)."""
    return len(os.listdir("/proc/self/task"))


def network() -> int:
    """The threads that serve the process's MQTT connections (the loop and its helpers, mqttloop.py)."""
    return sum(1 for t in threading.enumerate() if t.name.startswith("td2adaptor-mqtt"))


class Recorder:
    """Feedback events of every robot, by correlation."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.cond = threading.Condition()
        self.feedback: dict[str, list[dict[str, Any]]] = {}
        bus.subscribe("td2adaptor/+/+/+/feedback", self._on)
        bus.connect()

    def _on(self, msg: Message) -> None:
        event = json.loads(msg.payload)
        with self.cond:
            self.feedback.setdefault(str(event.get("correlation")), []).append(event["payload"])
            self.cond.notify_all()

    def states(self, correlation: str) -> list[str]:
        with self.cond:
            return [p["state"] for p in self.feedback.get(correlation, [])]

    def ends(self, correlation: str) -> list[dict[str, Any]]:
        with self.cond:
            return [p for p in self.feedback.get(correlation, []) if p.get("terminal")]


def action_model() -> Any:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "td.json"
        path.write_text(json.dumps(action_td()), encoding="utf-8")
        result = td2adaptor.compile(path, interfaces=[INTERFACES])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return result.model


def app_bus_for(bus_url: str, broker: LocalBroker | None) -> Bus:
    if broker is not None:
        return LocalBus(broker, "threads-app")
    from td2adaptor.runtime.bus.mqttbus import MqttBus
    from td2adaptor.runtime.bus.security import parse_broker_url

    return MqttBus(parse_broker_url(bus_url), client_id="threads-app", clean_start=True)


def goals(bus_url: str, count: int) -> None:
    """Every robot runs a ROS action goal (see the module docstring)."""
    local = bus_url == "local"
    model = action_model()
    actions = SimActions(step=STEP)  # its one thread is there before anything is counted
    broker = LocalBroker() if local else None
    robots = [f"fleet_{i:03d}" for i in range(count)]
    path = {r: GOAL_PATHS[i % len(GOAL_PATHS)] for i, r in enumerate(robots)}
    ports = {r: SimPort(model, sim(robot_id=r), readers={}, writers={}, actions=actions) for r in robots}
    run = {r: f"{r}-goal" for r in robots}
    figures: dict[str, Any] = {"before": counted(), "path": path}
    start = time.monotonic()

    def config(robot: str) -> RuntimeConfig:
        # the timeouts pass, and the finished goals end (8 s), once every goal runs
        timeout = 10.0 if path[robot] == "timeout" else 120.0
        return RuntimeConfig(robot=robot, bus=bus_url, call_timeout=1.0, mission_timeout=timeout, state_dir="")

    engines: list[Engine] = serve_fleet(
        model, lambda c: ports[c.robot], [config(r) for r in robots[:FIRST]], broker=broker
    )
    figures["first"] = counted()
    engines += serve_fleet(model, lambda c: ports[c.robot], [config(r) for r in robots[FIRST:]], broker=broker)
    figures["all"] = counted()
    figures["names"] = sorted({t.name.rstrip("0123456789") for t in threading.enumerate()})
    app_bus = app_bus_for(bus_url, broker)
    app = Recorder(app_bus)
    figures["app"] = counted()
    for r in robots:
        invoke = {"correlation": run[r], "payload": {"order": ORDERS[path[r]]}}
        app_bus.publish(f"td2adaptor/{r}/MathComponent/fibonacci", json.dumps(invoke).encode())
    during: list[int] = []
    running_at_once = False
    deadline = time.monotonic() + 150
    while time.monotonic() < deadline:
        during.append(counted())
        if not running_at_once and all("running" in app.states(run[r]) and not app.ends(run[r]) for r in robots):
            running_at_once = True  # every goal runs: now the cancels
            figures["all_running_after"] = round(time.monotonic() - start, 2)
            for r in robots:
                if path[r] == "cancelled":
                    cancel = {"correlation": run[r]}
                    app_bus.publish(f"td2adaptor/{r}/MathComponent/fibonacci/cancel", json.dumps(cancel).encode())
        if all(app.ends(run[r]) for r in robots):
            break
        time.sleep(0.01)
    figures["during"] = during
    figures["running_at_once"] = running_at_once
    figures["after"] = counted()
    figures["ends"] = {r: app.ends(run[r]) for r in robots}
    figures["states"] = {r: app.states(run[r]) for r in robots}
    for engine in engines:
        engine.stop()
    app_bus.close()
    end = time.monotonic() + 10  # the local bus's delivery thread ends on its own once its last client left
    while counted() > figures["before"] and time.monotonic() < end:
        time.sleep(0.01)
    figures["stopped"] = counted()
    print(json.dumps(figures), flush=True)


def main() -> None:
    logging.getLogger("td2adaptor").setLevel(logging.ERROR)  # the unreachable robots' failed queries
    bus_url = sys.argv[1]
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 100
    if sys.argv[3:] == ["goals"]:
        goals(bus_url, count)
        return
    local = bus_url == "local"
    model = rb1_model()
    broker = LocalBroker() if local else None
    robots = [f"fleet_{i:03d}" for i in range(count)]
    path = {r: PATHS[i % len(PATHS)] for i, r in enumerate(robots)}
    # a finished mission runs long enough for a poll to see it running on a loaded machine (at load 20-28, 16
    # of 100 missions of 5 s went queued -> finished)
    sims = {r: sim(10.0 if path[r] == "finished" else 60.0, robot_id=r) for r in robots}
    ports = {r: SimPort(model, sims[r]) for r in robots}

    def config(robot: str) -> RuntimeConfig:
        # the timeout path's mission timeout must pass after its mission runs, and no poll may time out before
        # the robot goes down: on a machine busier than its cores 34 of 100 missions ended (5 s mission timeout,
        # 1 s call timeout) before they ran; `unreachable` comes from a port that is down, at once
        timeout = 15.0 if path[robot] == "timeout" else 60.0
        return RuntimeConfig(
            robot=robot,
            bus=bus_url,
            poll_period=0.05,
            property_period=0.2,  # the sampled properties' timers run too
            call_timeout=5.0,
            mission_timeout=timeout,
            max_query_failures=3,
            state_dir="",
        )

    def port(c: RuntimeConfig) -> SimPort:
        return ports[c.robot]

    figures: dict[str, Any] = {"before": counted()}
    engines: list[Engine] = serve_fleet(model, port, [config(r) for r in robots[:FIRST]], broker=broker)
    figures["first"] = counted()
    engines += serve_fleet(model, port, [config(r) for r in robots[FIRST:]], broker=broker)
    figures["all"] = counted()
    figures["names"] = sorted({t.name.rstrip("0123456789") for t in threading.enumerate()})
    if local:
        app_bus: Bus = LocalBus(broker, "threads-app")
    else:
        from td2adaptor.runtime.bus.mqttbus import MqttBus
        from td2adaptor.runtime.bus.security import parse_broker_url

        app_bus = MqttBus(parse_broker_url(bus_url), client_id="threads-app", clean_start=True)
    app = Recorder(app_bus)
    figures["app"] = counted()
    run = {r: f"{r}-mission" for r in robots}
    for r in robots:
        invoke = {"correlation": run[r], "payload": GOAL}
        app_bus.publish(f"td2adaptor/{r}/GoToComponent/gotoRun", json.dumps(invoke).encode())
    during: list[int] = []
    acted: set[str] = set()
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        during.append(counted())
        for r in robots:
            if r in acted or "running" not in app.states(run[r]):
                continue
            acted.add(r)
            if path[r] == "cancelled":
                cancel = {"correlation": run[r]}
                app_bus.publish(f"td2adaptor/{r}/GoToComponent/gotoCancel", json.dumps(cancel).encode())
            elif path[r] == "unreachable":
                ports[r].down = True
        if all(app.ends(run[r]) for r in robots):
            break
        time.sleep(0.01)
    figures["during"] = during
    figures["in_flight"] = len(acted)
    figures["after"] = counted()
    figures["ends"] = {r: app.ends(run[r]) for r in robots}
    figures["states"] = {r: app.states(run[r]) for r in robots}
    figures["path"] = path
    for engine in engines:
        engine.stop()
    app_bus.close()
    end = time.monotonic() + 10  # the local bus's delivery thread ends on its own once its last client left
    while counted() > figures["before"] + network() and time.monotonic() < end:
        time.sleep(0.01)
    figures["stopped"] = counted()
    figures["network"] = network()
    print(json.dumps(figures), flush=True)


if __name__ == "__main__":
    main()
