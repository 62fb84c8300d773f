"""A command read on a robot connection whose session another process took over is not run, even when that
connection has not noticed yet (issue 32, "no command runs twice during a takeover"; node/share.py's gate for
ROS action goals, node/admitted.py `AckedPort` for procedure missions, plain calls and property writes).

A process of a shared fleet that hung (SIGSTOP) resumes; mosquitto closed its robot connection when the other
process took the session over (no DISCONNECT, the socket just closes), and the other process got the session's
commands and ran them. The resumed process reads a command that waited in its socket and its engine opens the
goal's mission before its MQTT loop has read the end of that socket: the gate saw the member connection's
acknowledgement of the admitted entry and a robot connection that still looked connected, and sent the goal a
second time (2 of ~30 loop runs of test_fleet_share_resume.py's `ros-action-goal` case). A procedure mission
waited for the same acknowledgement (and was not even gated on a port with calls that need no waiting thread,
as the rclpy and ROS 1 bridge ports have: it started from the engine's loop at once); plain calls and property
writes were never gated.

Real mosquitto, a real engine prepared as a shared fleet prepares it (`Share._prepare` of a real `Share`, not
started), a real paho client that takes the robot's session over. The order is forced: the engine's loop and
the process's MQTT serving loop are held; the member connection is served by the test (a `DrivenBus`), so the
broker's acknowledgement of the entry is read while the robot connection's closed socket is not.
"""

from __future__ import annotations

import json
import tempfile
import threading
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.backends.events.generator import generate as events
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import Model
from td2adaptor.runtime import loop
from td2adaptor.runtime.bus.drivenbus import DrivenBus
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.mqttloop import shared as serving_loop
from td2adaptor.runtime.bus.security import ConnectionSecurity, parse_broker_url
from td2adaptor.runtime.config import load_defaults, robot_config
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.events import now_rfc3339
from td2adaptor.runtime.node.app import serve
from td2adaptor.runtime.node.fleet import Fleet
from td2adaptor.runtime.node.roslink import RosLink
from td2adaptor.runtime.node.share import Share
from td2adaptor.runtime.ros.port import Answered, GoalListener, PortError
from td2adaptor.runtime.ros.simport import SimActions, SimPort
from tests.lowering.test_procedures import INTERFACES
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import bus_of, until
from tests.runtime.rb1 import rb1_model, sim, td_with_security
from tests.runtime.test_edge_node_plain_services import plain_td
from tests.runtime.threads_proc import action_model

ROBOT = "rb_00"
PROCEDURE = {"procedure": {"goals": [{"pose": {"x": 1.5, "y": 3.0}}]}}


class CountingActions(SimActions):
    """Simulated ROS action servers that count the goals they are sent."""

    def __init__(self) -> None:
        super().__init__(step=0.05)
        self.sent: list[Any] = []

    def start(self, payload: Any, listener: GoalListener) -> str:
        self.sent.append(payload)
        return super().start(payload, listener)


class QuickPort(SimPort):
    """The simulation with calls that need no waiting thread (`QuickCall`), as the rclpy and bridge ports have
    (answered at once here), and a record of the property writes."""

    written: list[tuple[str, Any]]

    def write_property(self, component: str, name: str, value: Any) -> None:
        self.written.append((name, value))
        super().write_property(component, name, value)

    def _quick(self, call: Callable[[], Any], on_done: Answered) -> bool:
        try:
            value, error = call(), None
        except PortError as exc:  # told, as a port tells it
            value, error = None, exc
        on_done(value, error)
        return True

    def try_start(self, component: str, action: str, payload: Any, timeout: float, on_done: Answered) -> bool:
        return self._quick(lambda: self.start(component, action, payload, timeout), on_done)

    def try_query(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        return self._quick(lambda: self.query(component, action, mission_id, timeout), on_done)

    def try_cancel(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        return self._quick(lambda: self.cancel(component, action, mission_id, timeout), on_done)

    def try_call(self, component: str, action: str, payload: Any, timeout: float, on_done: Answered) -> bool:
        return self._quick(lambda: self.call(component, action, payload, timeout), on_done)


def plain_model() -> Model:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "td.json"
        path.write_text(json.dumps(plain_td()), encoding="utf-8")
        result = td2adaptor.compile(path, interfaces=[INTERFACES])
    assert result.model is not None
    return result.model


@dataclass
class Case:
    model: Callable[[], Model]
    topic: str
    payload: dict[str, Any]
    ran: Callable[[QuickPort, CountingActions], list[Any]]  # what reached the robot


CASES = {
    "ros-action-goal": Case(action_model, "MathComponent/fibonacci", {"order": 3}, lambda _p, a: a.sent),
    "procedure": Case(
        rb1_model, "GoToComponent/gotoRun", PROCEDURE, lambda p, _a: [c for c in p.calls if c[1] == "gotoRun"]
    ),
    "plain-call": Case(plain_model, "BaseComponent/stop", {}, lambda p, _a: [c for c in p.calls if c[1] == "stop"]),
    "property-write": Case(rb1_model, "DoorComponent/door/write", {"data": 0.5}, lambda p, _a: p.written),
}


@pytest.mark.parametrize("kind", list(CASES))
def test_a_command_read_on_a_connection_whose_session_moved_unnoticed_is_not_run(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, kind: str
) -> None:
    case = CASES[kind]
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    settings = {"bus": broker.url, "poll_period": 0.05, "property_period": 0, "presence_period": 0}
    defaults = load_defaults(env={}, overrides={**settings, "state_dir": str(tmp_path / "state"), "fleet": "shared"})
    config = robot_config(defaults, ROBOT)
    model = case.model()
    actions = CountingActions()
    port = QuickPort(model, sim(0.3), actions=actions)
    port.written = []
    if kind == "ros-action-goal":  # no properties there
        port = QuickPort(model, sim(0.3), readers={}, writers={}, actions=actions)
        port.written = []

    def ran() -> list[Any]:
        return case.ran(port, actions)

    member = DrivenBus.sessionless(parse_broker_url(broker.url), None, "member-shared-test")
    member.connect()
    share = Share(Fleet(model, RosLink(), distro="ros2"), member, name="shared", root="td2adaptor")
    engine: Engine | None = None
    thief: AppClient | None = None
    engine_loop = loop.acquire()  # the process's engine loop, held below
    free_engine, free_serving = threading.Event(), threading.Event()
    try:
        engine = serve(model, port, config, prepare=share._prepare)
        robot_bus = bus_of(engine)
        assert isinstance(robot_bus, MqttBus)
        held_engine, held_serving = threading.Event(), threading.Event()

        def hold(held: threading.Event, free: threading.Event) -> None:
            held.set()
            free.wait(60)

        engine_loop.loop.post(hold, held_engine, free_engine)
        assert held_engine.wait(10)
        sender = AppClient(broker, ["test/nothing"])
        event_id = uuid.uuid4().hex
        event = {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": case.payload}
        sender.send(f"td2adaptor/{ROBOT}/{case.topic}", event)
        assert until(lambda: engine._queued >= 1, 20)  # read on the robot connection, waiting for the engine
        sender.close()

        # the process stands still: nothing is read on its robot connection from now on
        serving = serving_loop()
        serving.call_soon(lambda: hold(held_serving, free_serving))
        assert held_serving.wait(10)
        # another process takes the robot's session over: mosquitto closes the first connection and delivers the
        # session's unacknowledged command to the new one (which runs it, over there)
        thief = AppClient(broker, [f"td2adaptor/{ROBOT}/nothing"], client_id=robot_bus.client_id)
        assert until(lambda: any(e.get("id") == event_id for _t, e in list(thief.events)), 20)
        assert robot_bus.connected  # not noticed: its socket's end is not read

        free_engine.set()  # the engine takes the command (an invoke: its admitted entry published)
        if kind == "ros-action-goal":  # the gate waits on the engine's loop: the entry's acknowledgement read there
            assert until(lambda: bool(member._pending), 20)
            acknowledged = threading.Event()

            def flush() -> None:  # on the loop, which published it (the bus's one thread)
                if member.flush(10):
                    acknowledged.set()

            engine_loop.loop.post(flush)
            assert acknowledged.wait(20)
            done = threading.Event()
            engine_loop.loop.post(done.set)  # what the gate posted is handled before this
            assert done.wait(20)
        # run already (before: nothing asked the robot connection), or its round trip sent on the connection whose
        # socket's end is not read yet, waiting for an answer
        assert until(lambda: bool(ran()) or bool(getattr(robot_bus, "_trips", None)), 20)
        assert robot_bus.connected  # still not noticed
        # the broker has the entry (read on a pool thread, which waits there), or it ran without waiting for it
        assert until(lambda: bool(ran()) or not member._pending, 20)
        free_serving.set()  # the process reads the end of its robot connection
        assert until(lambda: not robot_bus.connected, 20)
        assert until(lambda: bool(ran()) or "not run here" in caplog.text, 20), caplog.text
        assert ran() == [], ran()  # the new owner runs it: never here
        assert until(engine.idle, 30)
    finally:
        free_engine.set()
        free_serving.set()
        if thief is not None:
            thief.close()
        if engine is not None:
            engine.stop()
        loop.release(engine_loop)
        member.close()
        broker.stop()


@pytest.mark.parametrize("version", ["5", "3.1.1"])
def test_the_robot_connections_round_trip_is_answered_under_the_generated_acl(tmp_path: Path, version: str) -> None:
    """The round trip is an UNSUBSCRIBE from a topic no ACL grants: the broker answers it all the same (a denial
    is an answer too), in both MQTT versions; a connection that is gone answers False, at once."""
    model = td_with_security(tmp_path, {"basic_sc": {"scheme": "basic"}})
    diags = Diagnostics()
    tree = events(model, GenOptions(extra=(("events.robots", [ROBOT]), ("events.fleet", "shared"))), diags)
    acl = tmp_path / "mosquitto.acl"
    acl.write_bytes(tree.files[f"{model.package_name}/mosquitto.acl"])
    broker = Mosquitto(tmp_path / "broker", users={ROBOT: "pass"}, acl=acl)
    broker.start()
    security = ConnectionSecurity(username=ROBOT, password="pass")
    bus = MqttBus(parse_broker_url(broker.url), security, client_id=f"td2adaptor-{ROBOT}", mqtt_version=version)
    try:
        bus.connect()
        told: list[bool] = []
        answered = threading.Event()

        def then(fine: bool) -> None:
            told.append(fine)
            answered.set()

        bus.round_trip(then)
        assert answered.wait(10) and told == [True], told
        bus.close()
        bus.round_trip(told.append)
        assert told == [True, False], told
    finally:
        bus.close()
        broker.stop()
