"""The property streams' own MQTT connection (runtime/bus/drivenbus.py), on a real mosquitto: served by the
thread that publishes on it (no network thread), it delivers in order at QoS 1 and 0, reads its
acknowledgements when stepped, keeps itself alive, reconnects after a broker restart (also when many are
served together, as a fleet's publishing thread does), and when the second connection cannot be made (MQTT
3.1.1; on MQTT 5 they use the robot's anyway) the streams use the robot's own. No mocks."""

from __future__ import annotations

import logging
import threading
import time

import pytest

from td2adaptor.model.events import Kind
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.bus.drivenbus import DrivenBus, twin
from td2adaptor.runtime.bus.drivenbus import serve as serve_all
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from td2adaptor.runtime.engine.streams import PropertyStreams, _Slot
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import rb1_model, sim


def driven(url: str, **kw: object) -> DrivenBus:
    bus = twin(MqttBus(parse_broker_url(url), client_id="robot-x", **kw))  # type: ignore[arg-type]
    bus.connect()
    return bus


def numbers(app: AppClient, topic: str) -> list[int]:
    with app.cond:
        return [e["n"] for t, e in app.events if t == topic]


def test_publishes_in_order_at_qos_1_and_0_and_reads_its_acknowledgements(broker: Mosquitto) -> None:
    app = AppClient(broker, ["d/#"])
    bus = driven(broker.url)
    try:
        assert bus.client_id == "robot-x-streams" and bus.clean_start and bus.will is None
        names = {t.name for t in threading.enumerate()}
        assert not any("robot-x-streams" in n for n in names), names
        for n in range(500):
            bus.publish("d/one", b'{"n": %d}' % n, qos=1)
            bus.publish("d/zero", b'{"n": %d}' % n, qos=0)
            if n % 50 == 0:
                bus.step()
        assert bus.flush(10.0), "every PUBACK read by stepping"
        app.wait(lambda _e: len(numbers(app, "d/one")) == 500 and len(numbers(app, "d/zero")) == 500)
        assert numbers(app, "d/one") == numbers(app, "d/zero") == list(range(500))
        assert app.qos == {"d/one": {1}, "d/zero": {0}}
        with bus._lock:  # a QoS 0 message's on_publish is no early PUBACK of a later QoS 1 one
            assert not bus._acked_early and not bus._unacked and not bus._pending
    finally:
        bus.close()
        app.close()


def test_stepping_keeps_it_alive_and_it_reconnects_after_a_broker_restart(broker: Mosquitto) -> None:
    app = AppClient(broker, ["d/#"])
    bus = driven(broker.url, keepalive=1, reconnect_delay=(1, 1))
    try:
        end = time.monotonic() + 3.5  # the broker drops a client silent for 1.5 keep-alive periods
        while time.monotonic() < end:
            bus.step()
            time.sleep(0.05)
        bus.publish("d/alive", b'{"n": 1}')
        app.wait(lambda _e: numbers(app, "d/alive") == [1])
        assert bus.connects == 1, "one connection all along"
        broker.restart()
        assert until(lambda: (bus.step(), bus.connects)[1] == 2, 15.0), "reconnected by stepping"
        app.connected.wait(10)
        bus.publish("d/alive", b'{"n": 2}')
        assert bus.flush(5.0)
        app.wait(lambda _e: 2 in numbers(app, "d/alive"), timeout=15)
    finally:
        bus.close()
        app.close()


def test_many_served_together_read_their_acknowledgements_stay_alive_and_reconnect(broker: Mosquitto) -> None:
    """`serve` (one poll for all, as the process's publishing thread serves a fleet's stream connections) does
    for each what `step` does for one: every PUBACK read, keep-alive past 1.5 periods, reconnect after a restart."""
    app = AppClient(broker, ["m/#"])
    buses = [
        twin(MqttBus(parse_broker_url(broker.url), client_id=f"robot-{i}", keepalive=1, reconnect_delay=(1, 1)))
        for i in range(5)
    ]
    for bus in buses:
        bus.connect()

    def pending() -> int:
        return sum(len(bus._pending) for bus in buses)

    try:
        for n in range(200):
            for i, bus in enumerate(buses):
                bus.publish(f"m/{i}", b'{"n": %d}' % n, qos=1)
            if n % 20 == 0:
                serve_all(buses)
        assert until(lambda: (serve_all(buses), pending())[1] == 0, 10.0), "every PUBACK read by serving"
        app.wait(lambda _e: all(numbers(app, f"m/{i}") == list(range(200)) for i in range(5)))
        end = time.monotonic() + 3.5  # the broker drops a client silent for 1.5 keep-alive periods
        while time.monotonic() < end:
            serve_all(buses)
            time.sleep(0.05)
        assert [bus.connects for bus in buses] == [1] * 5, "one connection each all along"
        broker.restart()
        assert until(lambda: (serve_all(buses), [b.connects for b in buses])[1] == [2] * 5, 15.0), "all reconnected"
        app.connected.wait(10)
        for i, bus in enumerate(buses):
            bus.publish(f"m/{i}", b'{"n": 1000}')
        assert until(lambda: (serve_all(buses), pending())[1] == 0, 10.0)
        app.wait(lambda _e: all(1000 in numbers(app, f"m/{i}") for i in range(5)), timeout=15)
    finally:
        for bus in buses:
            bus.close()
        app.close()


def test_streams_use_the_robots_own_connection_when_they_cannot_have_their_own(
    broker: Mosquitto, caplog: pytest.LogCaptureFixture
) -> None:
    """The stream connection cannot be made (here: the broker is gone when the streams start): one warning,
    and the events go through the robot's own connection (envelope and WoT form), once it is back. (On MQTT
    3.1.1: on MQTT 5 the streams use the robot's connection anyway, test_property_streams.py.)"""
    model = rb1_model()
    config = RuntimeConfig(
        robot="solo", bus=broker.url, property_period=0, state_dir="", call_timeout=2, mqtt_version="3.1.1"
    )
    engine = serve(model, SimPort(model, sim(0.2)), config)
    spec = engine.catalog.find(Kind.PROPERTY, "availability")
    try:
        broker.stop()
        with caplog.at_level(logging.WARNING, logger="td2adaptor.runtime"):
            streams = PropertyStreams(engine.outbox, engine.port, engine.model, [])
            streams.start()
        assert streams.out is None
        assert "no connection of its own for the property streams" in caplog.text
        streams.stop()
        broker.start()
        app = AppClient(broker, ["td2adaptor/solo/#"])
        assert until(lambda: engine.bus.bus.connected, 15.0)  # type: ignore[attr-defined]
        slot = _Slot(engine.outbox, spec)
        assert slot.out is None
        slot.emit({"value": 42})
        topic = spec.topic("solo")
        app.wait(lambda ev: {topic, f"td2adaptor/solo/{WOT_LEVEL}/{spec.component}/availability"} <= {t for t, _ in ev})
        with app.cond:
            assert next(e for t, e in app.events if t == topic)["payload"] == {"value": 42}
        app.close()
    finally:
        engine.stop()
