"""The in-process bus keeps the MQTT semantics the engine relies on; the same checks run on MqttBus too."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from td2adaptor.runtime import BusError, LocalBroker, LocalBus, Message
from td2adaptor.runtime.bus.bus import Bus, topic_matches, valid_filter
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from tests.runtime.broker import Mosquitto


class Inbox:
    def __init__(self) -> None:
        self.got: list[Message] = []
        self.cond = threading.Condition()

    def __call__(self, msg: Message) -> None:
        with self.cond:
            self.got.append(msg)
            self.cond.notify_all()

    def wait(self, n: int, timeout: float = 10) -> list[Message]:
        with self.cond:
            assert self.cond.wait_for(lambda: len(self.got) >= n, timeout), self.got
            return list(self.got)


def test_topic_filters() -> None:
    assert topic_matches("a/+/c", "a/b/c") and not topic_matches("a/+/c", "a/b/c/d")
    assert topic_matches("a/#", "a") and topic_matches("a/#", "a/b/c") and topic_matches("#", "x/y")
    assert not topic_matches("#", "$SYS/x") and topic_matches("+/+", "a/b") and not topic_matches("+", "a/b")
    assert valid_filter("a/+/#") and not valid_filter("a/#/b") and not valid_filter("a/b+") and not valid_filter("")


BusFactory = Callable[[str], Bus]


@pytest.fixture(params=["local", "mqtt"])
def make_bus(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[BusFactory]:
    """Bus clients on one local broker, or on one real mosquitto."""
    made: list[Bus] = []
    if request.param == "local":
        broker = LocalBroker()

        def local(client_id: str) -> Bus:
            bus = LocalBus(broker, client_id)
            made.append(bus)
            return bus

        yield local
    else:
        mosquitto = Mosquitto(tmp_path / "broker")
        mosquitto.start()

        def mqtt(client_id: str) -> Bus:
            bus = MqttBus(parse_broker_url(mosquitto.url), client_id=client_id)
            made.append(bus)
            return bus

        yield mqtt
        for bus in made:
            bus.close()
        mosquitto.stop()
        return
    for bus in made:
        bus.close()


def test_wildcards_order_and_retained(make_bus: BusFactory) -> None:
    sub, pub = make_bus("sub"), make_bus("pub")
    inbox, other = Inbox(), Inbox()
    pub.connect()
    pub.publish("t/r1/status", b"online", retain=True)
    pub.publish("t/r2/status", b"online", retain=True)
    pub.publish("t/r2/status", b"", retain=True)  # deletes the retained message
    assert pub.flush(5)
    sub.subscribe("t/+/status", inbox)
    sub.subscribe("t/r1/x/#", other)
    sub.connect()
    first = inbox.wait(1)[0]
    assert (first.topic, first.payload, first.retain) == ("t/r1/status", b"online", True)
    for i in range(300):
        pub.publish("t/r1/x/y", str(i).encode())
    got = other.wait(300)
    assert [int(m.payload) for m in got] == list(range(300))  # per-topic order
    assert not any(m.retain for m in got)
    time.sleep(0.1)
    assert [m.topic for m in inbox.got] == ["t/r1/status"]  # r2 was deleted, x/y does not match


def test_persistent_session_keeps_messages_while_away(make_bus: BusFactory) -> None:
    sub, pub = make_bus("keeper"), make_bus("pub")
    inbox = Inbox()
    sub.subscribe("q/#", inbox)
    sub.connect()
    pub.connect()
    pub.publish("q/1", b"before")
    inbox.wait(1)
    sub.close()
    for i in range(5):
        pub.publish("q/1", f"away{i}".encode())
    assert pub.flush(5)
    again = make_bus("keeper")  # same client id, clean_start False: the session and its queue are back
    again.subscribe("q/#", inbox)
    again.connect()
    got = inbox.wait(6)
    assert [m.payload for m in got] == [b"before"] + [f"away{i}".encode() for i in range(5)]


def test_a_qos_0_subscription_keeps_nothing_while_away(make_bus: BusFactory) -> None:
    """What the WoT command topics rely on (issue 16): mosquitto and the local bus queue for an absent client
    only what its QoS 1 subscriptions match."""
    sub, pub = make_bus("half-keeper"), make_bus("pub")
    kept, dropped = Inbox(), Inbox()
    sub.subscribe("q/#", kept)
    sub.subscribe("w/#", dropped, qos=0)
    sub.connect()
    pub.connect()
    sub.close()
    pub.publish("q/1", b"away")
    pub.publish("w/1", b"away")
    assert pub.flush(5)
    again = make_bus("half-keeper")
    again.subscribe("q/#", kept)
    again.subscribe("w/#", dropped, qos=0)
    again.connect()
    assert [m.payload for m in kept.wait(1)] == [b"away"]
    pub.publish("w/1", b"back")
    assert [m.payload for m in dropped.wait(1)] == [b"back"]  # the one sent while away never came


def test_a_retained_message_keeps_its_flag_for_a_subscriber_already_there(make_bus: BusFactory) -> None:
    """Issue 30, item 3: MQTT clears the retain flag of a message delivered to a client already subscribed,
    so a command published retained while the node was online looked live and ran. The node subscribes with
    MQTT 5's retain-as-published and the local bus keeps the flag the same way: a retained message, and the
    empty retained message that clears it, arrive flagged; a plain one does not; at QoS 0 too."""
    sub, pub = make_bus("flag-keeper"), make_bus("pub")
    kept, loose = Inbox(), Inbox()
    sub.subscribe("r/#", kept)
    sub.subscribe("w/#", loose, qos=0)
    sub.connect()
    pub.connect()
    for topic in ("r/1", "w/1"):
        pub.publish(topic, b"live")
        pub.publish(topic, b"kept", retain=True)
        pub.publish(topic, b"", retain=True)  # clears it: delivered, flagged too
    want = [(b"live", False), (b"kept", True), (b"", True)]
    assert [(m.payload, m.retain) for m in kept.wait(3)] == want
    assert [(m.payload, m.retain) for m in loose.wait(3)] == want


def test_local_redelivers_when_a_handler_fails() -> None:
    broker = LocalBroker()
    bus = LocalBus(broker, "flaky")
    calls: list[bytes] = []

    def flaky(msg: Message) -> None:
        calls.append(msg.payload)
        if len(calls) < 3:
            raise RuntimeError("not yet")

    bus.subscribe("x", flaky)
    bus.connect()
    bus.publish("x", b"1")
    assert bus.drain(5)
    assert calls == [b"1", b"1", b"1"]  # at least once
    bus.close()


def test_local_will_only_on_crash_and_clean_start() -> None:
    broker = LocalBroker()
    watcher, inbox = LocalBus(broker, "watcher"), Inbox()
    watcher.subscribe("s/#", inbox)
    watcher.connect()
    will = Message("s/a", b"offline", True)
    a = LocalBus(broker, "a", will=will, birth=Message("s/a", b"online", True))
    a.connect()
    a.close()
    b = LocalBus(broker, "b", will=Message("s/b", b"offline", True))
    b.connect()
    b.crash()
    got = inbox.wait(2)
    time.sleep(0.05)
    assert [(m.topic, m.payload) for m in inbox.got] == [("s/a", b"online"), ("s/b", b"offline")], got
    with pytest.raises(BusError, match="already connected"):
        LocalBus(broker, "watcher").connect()
    with pytest.raises(BusError, match="invalid topic"):
        watcher.publish("s/+", b"")
    fresh = LocalBus(broker, "b", clean_start=True)
    fresh.connect()  # the old session (and its subscriptions) is gone
    fresh.close()
    watcher.close()


def test_a_hundred_local_clients_share_one_delivery_thread_and_keep_their_order() -> None:
    """One delivery thread per broker, not per client (a fleet of robots on the local bus); each client's
    messages in publish order; a handler may close its own client."""
    before = set(threading.enumerate())
    broker = LocalBroker()
    inboxes = [Inbox() for _ in range(100)]
    buses = [LocalBus(broker, f"c{i}") for i in range(100)]
    for i, (bus, inbox) in enumerate(zip(buses, inboxes, strict=True)):
        bus.subscribe(f"t/{i}", inbox)
        bus.connect()
    (deliverer,) = [t for t in threading.enumerate() if t not in before]
    assert deliverer.name == "td2adaptor-localbus"
    publisher = LocalBus(broker, "publisher")
    publisher.connect()
    for n in range(20):
        for i in range(100):
            publisher.publish(f"t/{i}", str(n).encode())
    for inbox in inboxes:
        assert [m.payload for m in inbox.wait(20)] == [str(n).encode() for n in range(20)]
    closer = LocalBus(broker, "closer")
    closed = threading.Event()

    def close_myself(msg: Message) -> None:
        closer.close()
        closed.set()

    closer.subscribe("bye", close_myself)
    closer.connect()
    publisher.publish("bye", b"")
    assert closed.wait(5)
    for bus in [*buses, publisher]:
        bus.close()
    deliverer.join(5)  # it ends once the broker's last client left
    assert [t for t in threading.enumerate() if t not in before] == []
