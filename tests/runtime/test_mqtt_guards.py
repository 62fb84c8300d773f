"""What the node keeps true across the life of its broker connection, on a real mosquitto (issue 30):
commands published retained while it is online are refused, every retained value it owns is back after a
broker restart that lost them, and a broker that lets anonymous clients in after a restart gets no command
through."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import threading
import uuid
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

from td2adaptor.model.wot import CORRELATION
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.bus.drivenbus import DrivenBus
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from td2adaptor.runtime.engine.replay import now_text
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import bus_of, until
from tests.runtime.rb1 import GOAL, check_outbound, rb1_model, sim, td_with_security, terminal

ROBOT = "rb1_guard"
ROOT = f"td2adaptor/{ROBOT}"
GOTO, CANCEL = f"{ROOT}/GoToComponent/gotoRun", f"{ROOT}/GoToComponent/gotoCancel"
WOT_GOTO, WOT_CANCEL = f"{ROOT}/wot-thing/GoToComponent/gotoRun", f"{ROOT}/wot-thing/GoToComponent/gotoCancel"


def config(broker: Mosquitto, **kw: Any) -> RuntimeConfig:
    base: dict[str, Any] = {"robot": ROBOT, "bus": broker.url, "poll_period": 0.05, "property_period": 0}
    return RuntimeConfig(**{**base, "call_timeout": 2, "state_dir": "", **kw})


def retained(broker: Mosquitto, topics: list[str], timeout: float = 5.0) -> dict[str, bytes]:
    """The retained message of each of `topics` that has one, as a client that subscribes now gets them."""
    host, port = broker.url.removeprefix("mqtt://").rsplit(":", 1)
    got: dict[str, bytes] = {}
    cond = threading.Condition()
    client = mqtt.Client(
        CallbackAPIVersion.VERSION2, client_id=f"late-{uuid.uuid4().hex[:8]}", protocol=MQTTProtocolVersion.MQTTv5
    )

    def on_message(_c: Any, _u: Any, msg: Any) -> None:
        with cond:
            if msg.retain and msg.topic in topics:
                got[msg.topic] = bytes(msg.payload)
                cond.notify_all()

    client.on_message = on_message
    client.on_connect = lambda c, *_: c.subscribe([(t, 1) for t in topics])
    client.connect(host, int(port), 30)
    client.loop_start()
    try:
        with cond:
            cond.wait_for(lambda: len(got) == len(topics), timeout)
            return dict(got)
    finally:
        client.disconnect()
        client.loop_stop()


# -- item 3: retained commands ---------------------------------------------------------------------------


def test_a_command_published_retained_while_the_node_is_online_is_refused(tmp_path: Path) -> None:
    """The broker hands a retained message to a client already subscribed with the retain flag cleared, so a
    retained invoke or cancel, envelope or WoT, ran (150 of 150). The node subscribes with retain-as-published
    (MQTT 5): each is answered `retained` and nothing reaches the robot; the empty retained messages that clear
    them are no command and get no answer; a command sent as usual still runs."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    model = rb1_model()
    port = SimPort(model, sim(0.1))
    engine = serve(model, port, config(broker))
    app = AppClient(broker, [f"{ROOT}/error", f"{ROOT}/+/+/feedback", f"{ROOT}/+/+/state"])
    commands = {
        GOTO: {"id": "ret-1", "correlation": "ret-env", "time": now_text(), "payload": GOAL},
        CANCEL: {"id": "ret-2", "correlation": "ret-cancel", "time": now_text()},
        WOT_GOTO: {**GOAL, CORRELATION: "ret-wot"},
        WOT_CANCEL: {CORRELATION: "ret-wot-cancel"},
    }
    try:
        for topic, event in commands.items():
            app.client.publish(topic, json.dumps(event).encode(), qos=1, retain=True).wait_for_publish(10)
        wanted = {"ret-env", "ret-cancel", "ret-wot", "ret-wot-cancel"}
        app.wait(lambda ev: wanted <= {e.get("correlation") for _, e in ev if e.get("type") == "error"})
        for _, error in app.events:
            assert error["type"] == "error" and error["payload"]["code"] == "retained", error
        for topic in commands:  # the clears, then on the same topics an invalid command, answered after them
            app.client.publish(topic, b"", qos=1, retain=True).wait_for_publish(10)
        marks = {GOTO: {"correlation": "m-env", "payload": 1}, CANCEL: {"correlation": "m-cancel", "x": 1}}
        marks |= {WOT_GOTO: {CORRELATION: "m-wot", "procedure": 1}, WOT_CANCEL: {CORRELATION: "m-wc", "x": 1}}
        for topic, event in marks.items():
            app.send(topic, event)
        wanted |= {"m-env", "m-cancel", "m-wot", "m-wc"}
        app.wait(lambda ev: wanted <= {e.get("correlation") for _, e in ev if e.get("type") == "error"})
        errors = [e for _, e in app.events if e.get("type") == "error"]
        assert sorted(e.get("correlation") for e in errors) == sorted(wanted), [e["payload"] for e in errors]
        assert [e for _, e in app.events if e.get("type") != "error"] == []
        assert port.calls == []  # nothing reached the robot
        app.send(GOTO, {"id": "live-1", "correlation": "live", "time": now_text(), "payload": GOAL})
        app.wait(terminal("feedback", "live"))
    finally:
        engine.stop()
        app.close()
        broker.stop()
    check_outbound(app.events)


# -- item 8: retained values after a broker restart ------------------------------------------------------


def test_every_retained_value_is_back_after_a_broker_restart_that_lost_them(tmp_path: Path) -> None:
    """A broker restarted without persistence forgets retained messages; the node published its TD and status
    again but its property values only once they changed, so a WoT consumer's readProperty waited forever.
    After the restart a new subscriber gets every retained message the node owns: TD, status and each property
    value on the envelope and the WoT topic, as they were."""
    broker = Mosquitto(tmp_path / "broker", persistence=False)
    broker.start()
    model = rb1_model()
    engine = serve(model, SimPort(model, sim(0.1)), config(broker, property_period=0.05, td_broker=broker.url))
    properties = ["AvailabilityComponent/availability", "PoseMarkerComponent/poseMarker"]
    topics = [f"{ROOT}/td", f"{ROOT}/status"]
    topics += [f"{ROOT}/{p}" for p in properties] + [f"{ROOT}/wot-thing/{p}" for p in properties]
    bus = bus_of(engine)
    assert isinstance(bus, MqttBus)
    try:
        assert until(lambda: engine.stats.get("out.property", 0) >= len(properties), 10) and bus.flush(5)
        before = retained(broker, topics)
        assert sorted(before) == sorted(topics)
        broker.restart()
        assert until(lambda: bus.connects >= 2, 20) and bus.flush(5)
        after = retained(broker, topics)
        assert sorted(after) == sorted(topics)
        assert after == before  # nothing changed on the robot: the same events, byte for byte
    finally:
        engine.stop()
        broker.stop()


def test_node_wot_reads_every_property_after_a_broker_restart_that_lost_them(tmp_path: Path) -> None:
    """What the issue saw: node-wot's readProperty waits for the retained value, and hung after such a
    restart. Now it reads each property at once, before the restart and after it."""
    from tests.runtime.test_edge_node_wot import node_modules

    modules = node_modules()
    broker = Mosquitto(tmp_path / "broker", persistence=False)
    broker.start()
    model = rb1_model()
    engine = serve(model, SimPort(model, sim(0.1)), config(broker, property_period=0.05, td_broker=broker.url))
    bus = bus_of(engine)
    assert isinstance(bus, MqttBus)

    def read() -> dict[str, Any]:
        command = ["node", str(Path(__file__).parent / "nodewot_read.js"), broker.url, ROBOT]
        env = {**os.environ, "NODE_PATH": str(modules)}
        out = subprocess.run(
            [*command, "availability", "poseMarker"], env=env, capture_output=True, text=True, timeout=30
        )
        assert out.returncode == 0, out.stdout + out.stderr
        return {line["name"]: line["value"] for line in map(json.loads, out.stdout.splitlines())}

    try:
        assert until(lambda: engine.stats.get("out.property", 0) >= 2, 10) and bus.flush(5)
        before = read()
        assert sorted(before) == ["availability", "poseMarker"]
        broker.restart()
        assert until(lambda: bus.connects >= 2, 20) and bus.flush(5)
        assert read() == before
    finally:
        engine.stop()
        broker.stop()


def test_a_stream_connection_publishes_its_retained_values_again_after_a_broker_restart(tmp_path: Path) -> None:
    """The property streams publish on a connection of their own (drivenbus.py), which must do the same."""
    broker = Mosquitto(tmp_path / "broker", persistence=False)
    broker.start()
    bus = DrivenBus(parse_broker_url(broker.url), client_id="streams", clean_start=True, session_expiry=0)
    try:
        bus.connect()
        bus.publish("s/a", b"1", retain=True)
        bus.publish("s/b", b"2", retain=True, qos=0)
        bus.publish("s/c", b"3", retain=True)
        bus.publish("s/c", b"", retain=True)  # cleared: not the node's any more
        bus.publish("s/d", b"not retained")
        assert bus.flush(5)
        assert retained(broker, ["s/a", "s/b"]) == {"s/a": b"1", "s/b": b"2"}
        broker.restart()
        assert until(lambda: (bus.step(), bus.connects >= 2)[1], 20, 0.05)
        assert bus.flush(5)
        assert retained(broker, ["s/a", "s/b", "s/c", "s/d"], timeout=2) == {"s/a": b"1", "s/b": b"2"}
    finally:
        bus.close()
        broker.stop()


# -- item 9: the anonymous-broker check on every connection ----------------------------------------------


def test_a_broker_restarted_open_to_anonymous_clients_runs_no_command(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The node checked at start only that a broker refuses anonymous clients when the TD requires
    authentication: restarted with `allow_anonymous true`, it was rejoined and an anonymous client moved the
    robot. The node checks on every connection before anything from it is handled: it stops serving that
    broker, says why, and the anonymous command never runs (not even once the broker is fixed: the node has
    stopped)."""
    broker = Mosquitto(tmp_path / "broker", users={"robot": "s3cret", "app": "app-pass"})
    broker.start()
    model = td_with_security(tmp_path, {"basic_sc": {"scheme": "basic"}})
    port = SimPort(model, sim(0.1))
    env = {"TD2ADAPTOR_MQTT_USERNAME": "robot", "TD2ADAPTOR_MQTT_PASSWORD": "s3cret"}
    engine = serve(model, port, config(broker), env=env)
    halted: list[str] = []
    engine.on_halt.append(halted.append)
    bus = bus_of(engine)
    assert isinstance(bus, MqttBus)
    anonymous: AppClient | None = None
    try:
        app = AppClient(broker, [f"{ROOT}/+/+/feedback"], username="app", password="app-pass")
        app.send(GOTO, {"id": "ok-1", "correlation": "before", "time": now_text(), "payload": GOAL})
        app.wait(terminal("feedback", "before"))
        app.close()
        calls = len(port.calls)
        broker.conf.write_text(broker.conf.read_text().replace("allow_anonymous false", "allow_anonymous true"))
        with caplog.at_level(logging.ERROR, logger="td2adaptor"):
            broker.restart()
            assert until(lambda: bool(halted) or bus.connects >= 2, 20)
            anonymous = AppClient(broker, [f"{ROOT}/#"])  # it really gets in
            anonymous.send(GOTO, {"id": "anon-1", "correlation": "anon", "time": now_text(), "payload": GOAL})
            assert not until(lambda: len(port.calls) > calls, 3.0)  # (the old node ran it within 0.1 s)
        assert len(halted) == 1 and "accepts clients without credentials" in halted[0], halted
        assert engine.failure == halted[0]
        assert any("accepts clients without credentials" in r.getMessage() for r in caplog.records)
        assert not bus.connected
        assert [t for t, e in anonymous.events if e.get("correlation") == "anon" and t != GOTO] == []  # no answer
        status = [e["payload"]["state"] for t, e in anonymous.events if t == f"{ROOT}/status"]
        assert status[-1:] == ["offline"], status  # it does not look online on that broker
    finally:
        if anonymous is not None:
            anonymous.close()
        engine.stop()
        broker.stop()
