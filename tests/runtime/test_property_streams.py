"""Property streams (runtime/engine/streams.py) without ROS, on a real mosquitto: on MQTT 5 they publish on the
robot's own connection, whose no-local keeps the node's own values from coming back to it; a throttled
property's message that only waits for its interval's end does not wake the publishing thread, and its latest
message is still published when the interval ends. No mocks."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from td2adaptor.model.events import EventSpec, Kind
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.engine.streams import PropertyStreams, Pump, _Slot
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.rb1 import rb1_model, sim


def availability_node(broker: Mosquitto, robot: str) -> tuple[Engine, EventSpec, str, str, AppClient]:
    """A node serving the simulated RB-1 `robot` on `broker`, its `availability` property's spec, envelope and WoT
    topics, and an application that subscribes to both."""
    model = rb1_model()
    config = RuntimeConfig(robot=robot, bus=broker.url, property_period=0, state_dir="", call_timeout=2)
    engine = serve(model, SimPort(model, sim(0.2)), config)
    spec = engine.catalog.find(Kind.PROPERTY, "availability")
    topic, wot = spec.topic(robot), f"td2adaptor/{robot}/{WOT_LEVEL}/{spec.component}/availability"
    return engine, spec, topic, wot, AppClient(broker, [topic, wot])


def test_the_nodes_own_property_values_do_not_come_back_to_it(broker: Mosquitto) -> None:
    """The node's command filters match the topics of its property values (envelope and WoT form). Published on
    a connection of their own, each value came back to the node twice, to be read and dropped (200 a second for
    a fleet of 100 RB-1s); on the robot's own connection, which asks for no-local, none comes back. Subscribers
    still get both forms."""
    engine, spec, topic, wot, app = availability_node(broker, "echo")
    client: Any = engine.bus.bus._client  # type: ignore[attr-defined]
    heard: list[str] = []
    on_message = client.on_message

    def counting(c: Any, userdata: Any, message: Any) -> None:
        heard.append(message.topic)
        on_message(c, userdata, message)

    client.on_message = counting
    streams = PropertyStreams(engine.outbox, engine.port, engine.model, [])
    streams.start()
    try:
        slot = _Slot(engine.outbox, spec)
        slot.out = streams.out
        for n in range(20):
            slot.emit({"value": n})
        assert until(lambda: [p["value"] for p in payloads(app, topic)] == list(range(20)), 10.0)
        assert until(lambda: len([t for t, _ in app.events if t == wot]) == 20, 10.0), "the WoT form too"
        time.sleep(0.5)  # an echo would have come by now
        assert [t for t in heard if t in (topic, wot)] == [], "the node's own values came back to it"
        assert streams.out is None, "the robot's own connection"
    finally:
        streams.stop()
        app.close()
        engine.stop()


class Waits(threading.Condition):
    """The publishing thread's condition, counting its waits (each is one turn of the thread)."""

    def __init__(self) -> None:
        super().__init__(threading.Lock())
        self.count = 0

    def wait(self, timeout: float | None = None) -> bool:
        self.count += 1
        return super().wait(timeout)


def test_a_throttled_message_waiting_for_its_interval_does_not_wake_the_publishing_thread(
    broker: Mosquitto,
) -> None:
    """A fleet's hundred robots at 1 s per property: each property's first message after an event only schedules
    the next one, and woke the publishing thread for nothing (its wait ends at the earliest timer anyway): 200
    turns a second of a thread that had nothing to publish. Now only a timer earlier than every other wakes it."""
    model = rb1_model()
    config = RuntimeConfig(robot="pumped", bus=broker.url, property_period=0, state_dir="", property_interval=1.0)
    engine = serve(model, SimPort(model, sim(0.2)), config)
    spec = engine.catalog.find(Kind.PROPERTY, "availability")
    topic = spec.topic("pumped")
    app = AppClient(broker, [topic])
    pump = Pump()
    pump.cond = waits = Waits()
    with pump.cond:
        pump._users = 1
        pump._thread = threading.Thread(target=pump._run, name="test-properties", daemon=True)
        pump._thread.start()
    slots = [_Slot(engine.outbox, spec) for _ in range(40)]
    try:
        for i, slot in enumerate(slots):  # the first message of each: published at once
            pump.put(slot, {"slot": i, "n": 0})
        assert until(lambda: len(payloads(app, topic)) == len(slots), 10.0), payloads(app, topic)
        time.sleep(0.05)
        before = waits.count
        for n in (1, 2, 3):  # within the interval: the latest of them waits for its end
            for i, slot in enumerate(slots):
                pump.put(slot, {"slot": i, "n": n})
                time.sleep(0.002)  # time for the thread to turn, had it been woken
        woken = waits.count - before
        assert until(lambda: len(payloads(app, topic)) == 2 * len(slots), 10.0), payloads(app, topic)
        assert sorted(p["slot"] for p in payloads(app, topic)[len(slots) :]) == list(range(len(slots)))
        assert all(p["n"] == 3 for p in payloads(app, topic)[len(slots) :]), "the latest message of each"
        assert woken <= 3, f"the publishing thread turned {woken} times for {3 * len(slots)} throttled messages"
    finally:
        with pump.cond:
            thread, pump._thread = pump._thread, None
            pump.cond.notify()
        if thread is not None:
            thread.join(5.0)
        app.close()
        engine.stop()


def payloads(app: AppClient, topic: str) -> list[Any]:
    with app.cond:
        return [e["payload"] for t, e in app.events if t == topic]


def until(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def test_a_property_event_and_its_wot_form_go_out_in_one_send(broker: Mosquitto) -> None:
    """A fleet's idle node publishes 200 property events a second (100 RB-1s, two properties each at one message
    a second), each with its WoT form: written one after the other, two sends and two acknowledgements to read
    for each. On the robot's own connection they go out together, in one send, as the engine's events do
    (`MqttBus.batch`); both still arrive, envelope first."""
    engine, spec, topic, wot, app = availability_node(broker, "onesend")
    client: Any = engine.bus.bus._client  # type: ignore[attr-defined]
    streams = PropertyStreams(engine.outbox, engine.port, engine.model, [])
    streams.start()
    sends: list[int] = []
    send = client._sock_send
    try:
        assert streams.out is None, "the robot's own connection"
        slot = _Slot(engine.outbox, spec)

        def counting(data: bytes) -> int:
            sends.append(len(data))
            return int(send(data))

        client._sock_send = counting
        for n in range(20):
            slot.emit({"value": n})
        assert until(lambda: [p["value"] for p in payloads(app, topic)] == list(range(20)), 10.0)
        assert until(lambda: len([t for t, _ in app.events if t == wot]) == 20, 10.0), "the WoT form too"
        mine = [t for t, _ in app.events if t in (topic, wot)]
        assert mine == [topic, wot] * 20, "each event before its WoT form"
        assert len(sends) <= 20, f"{len(sends)} sends for 20 property events and their WoT forms"
    finally:
        client._sock_send = send
        streams.stop()
        app.close()
        engine.stop()
