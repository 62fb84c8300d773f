"""The robots' MQTT connections served by one thread of the process (runtime/mqttloop.py), on a real mosquitto:
the thread count does not grow with the robots; publishes from many threads are written at once; the loop
keeps every connection alive, reconnects it after a broker restart and reads TLS bursts whole; a slow check of
one connection (the anonymous-broker probe) stalls no other, and what arrives on the checked one is handled only
once the check passed, in order, while nothing is written there before."""

from __future__ import annotations

import socket
import threading
import time
from pathlib import Path
from typing import Any

from td2adaptor.runtime import RuntimeConfig, serve_fleet
from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import ConnectionSecurity, TlsOptions, parse_broker_url
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.certs import make_certs
from tests.runtime.client import AppClient
from tests.runtime.edge import bus_of, until
from tests.runtime.rb1 import GOAL, rb1_model, sim, terminal


def network_threads() -> list[str]:
    """The names of the threads that serve MQTT connections: paho's own (`loop_start`) or the runtime's."""
    return sorted(t.name for t in threading.enumerate() if "mqtt" in t.name.lower() or "paho" in t.name.lower())


def fleet_threads(broker: Mosquitto, robots: int) -> tuple[list[str], int]:
    """Start `robots` robots in one process (`serve_fleet`, simulated), check that each is served (a mission on
    the last one, its subscriptions and birth on every one), and return the network threads and all threads
    counted while they run."""
    model = rb1_model()
    names = [f"loop_{robots}_{i}" for i in range(robots)]
    configs = [
        RuntimeConfig(robot=n, bus=broker.url, poll_period=0.05, property_period=0, call_timeout=2, state_dir="")
        for n in names
    ]
    engines = serve_fleet(model, lambda c: SimPort(model, sim(0.05)), configs)
    try:
        assert all(isinstance(bus_of(e), MqttBus) and bus_of(e).connected for e in engines)
        threads, total = network_threads(), threading.active_count()
        app = AppClient(broker, [f"td2adaptor/{names[-1]}/+/+/feedback"])
        try:
            app.send(f"td2adaptor/{names[-1]}/GoToComponent/gotoRun", {"correlation": "served", "payload": GOAL})
            app.wait(terminal("feedback", "served"))
        finally:
            app.close()
        return threads, total
    finally:
        for engine in engines:
            engine.stop()


def test_the_network_threads_of_a_fleet_process_do_not_grow_with_its_robots(broker: Mosquitto) -> None:
    """paho's `loop_start` gave every robot connection a network thread (5 robots: 5, 20 robots: 20); one
    thread of the process serves them all now."""
    five, total_five = fleet_threads(broker, 5)
    twenty, total_twenty = fleet_threads(broker, 20)
    assert five == twenty, (five, twenty)
    assert len(twenty) <= 5, twenty  # the serving thread (and at most its few helpers)
    assert not [n for n in twenty if n.startswith("paho")], twenty
    print(f"threads: 5 robots {total_five}, 20 robots {total_twenty}; MQTT: {twenty}")


def test_publishes_from_many_threads_are_written_at_once(broker: Mosquitto) -> None:
    """Eight threads publish one message at a time, each waiting for a subscriber to get it before the next,
    while messages keep arriving for the bus: every one arrives within 3 s (a lost wake-up of the serving thread
    would leave one unwritten until the next keep-alive, 30 s; a loaded machine pauses a whole second at times),
    in each thread's order."""
    app = AppClient(broker, ["many/out/#"])
    bus = MqttBus(parse_broker_url(broker.url), client_id="many-threads", keepalive=30)
    got: list[bytes] = []
    bus.subscribe("many/in", lambda m: got.append(m.payload))
    bus.connect()
    failures: list[str] = []
    rounds = 60

    def seen(topic: str) -> list[int]:
        with app.cond:
            return [e["n"] for t, e in app.events if t == topic]

    def publisher(k: int) -> None:
        topic = f"many/out/{k}"
        for n in range(rounds):
            bus.publish(topic, b'{"n": %d}' % n, qos=n % 2)
            start = time.monotonic()
            with app.cond:
                if not app.cond.wait_for(lambda n=n: n in [e["n"] for t, e in app.events if t == topic], 5.0):
                    failures.append(f"thread {k}: message {n} not written within 5 s")
                    return
            if time.monotonic() - start > 3.0:
                failures.append(f"thread {k}: message {n} took {time.monotonic() - start:.2f} s")

    def inbound() -> None:
        for n in range(rounds * 4):
            app.client.publish("many/in", b"%d" % n, qos=1)
            time.sleep(0.002)

    threads = [threading.Thread(target=publisher, args=(k,)) for k in range(8)]
    threads.append(threading.Thread(target=inbound))
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
        assert not failures, failures
        for k in range(8):
            assert seen(f"many/out/{k}") == list(range(rounds))
        assert until(lambda: len(got) == rounds * 4, 10), len(got)
        assert got == [b"%d" % n for n in range(rounds * 4)]
    finally:
        bus.close()
        app.close()


def test_the_loop_keeps_a_connection_alive_and_reconnects_it_after_a_broker_restart(broker: Mosquitto) -> None:
    """Keep-alive 1 s: the broker drops a client silent for 1.5 s, so the loop's PINGREQs keep it; after a
    restart the connection comes back (after the back-off), with its subscription and its persistent session:
    what was published for it while it was away is delivered."""
    got: list[bytes] = []
    bus = MqttBus(parse_broker_url(broker.url), client_id="alive", keepalive=1, reconnect_delay=(1, 2))
    bus.subscribe("alive/in", lambda m: got.append(m.payload))
    bus.connect()
    try:
        time.sleep(3.5)
        assert bus.connects == 1 and bus.connected, "one connection all along"
        broker.stop()
        assert until(lambda: not bus.connected, 10)
        time.sleep(2.5)  # a few failed attempts (1 s, then 2 s apart)
        broker.start()
        app = AppClient(broker, ["alive/none"])
        try:
            app.send("alive/in", b"while away")  # queued in the bus's session if it is not back yet
            assert until(lambda: bus.connects == 2, 15), "reconnected"
            app.send("alive/in", b"after")
            assert until(lambda: got == [b"while away", b"after"], 10), got
        finally:
            app.close()
    finally:
        bus.close()


def test_closing_a_client_that_waits_to_reconnect_returns_at_once(broker: Mosquitto) -> None:
    """A client whose broker is gone waits its back-off (here 4 s) before the next attempt: closing it then
    ends it at once, not when the attempt was due."""
    bus = MqttBus(parse_broker_url(broker.url), client_id="gone", reconnect_delay=(4, 8))
    bus.connect()
    broker.stop()
    assert until(lambda: not bus.connected, 10)
    time.sleep(0.5)
    start = time.monotonic()
    bus.close()
    assert time.monotonic() - start < 2


def test_a_burst_over_tls_is_read_whole(tmp_path: Path) -> None:
    """TLS decrypts whole records: bytes already decrypted are no event for the selector. A burst of 500
    messages over TLS is read to the end, none left waiting for the next keep-alive."""
    certs = make_certs(tmp_path / "certs")
    broker = Mosquitto(tmp_path / "broker", tls=(certs.ca, certs.server_cert, certs.server_key))
    broker.start()
    address = parse_broker_url(f"mqtts://127.0.0.1:{broker.port}")
    tls = ConnectionSecurity(None, None, TlsOptions(str(certs.ca), str(certs.client_cert), str(certs.client_key)), ())
    got: list[bytes] = []
    reader = MqttBus(address, tls, client_id="tls-reader")
    reader.subscribe("burst/#", lambda m: got.append(m.payload))
    writer = MqttBus(address, tls, client_id="tls-writer", clean_start=True, session_expiry=0)
    try:
        reader.connect()
        writer.connect()
        for n in range(500):
            writer.publish("burst/x", b"%d" % n)
        assert writer.flush(10)
        assert until(lambda: len(got) == 500, 10), len(got)
        assert got == [b"%d" % n for n in range(500)]
    finally:
        writer.close()
        reader.close()
        broker.stop()


class SlowCheck:
    """A connection check (the role of app.py's anonymous-broker probe) that passes at once, or, once
    `slow` is set, only when the test releases it."""

    def __init__(self) -> None:
        self.slow = False
        self.checking = threading.Event()
        self.release = threading.Event()

    def __call__(self) -> str | None:
        if self.slow:
            self.checking.set()
            assert self.release.wait(30)
        return None


def test_a_slow_check_of_one_connection_stalls_no_other_and_holds_what_arrives(broker: Mosquitto) -> None:
    """After a broker restart, robot a's new connection is checked, slowly. Meanwhile robot b (served by the
    same thread) gets its messages; robot a handles nothing of what arrives, and writes nothing there: not its
    birth, not a publish made meanwhile, not the 300 messages it published while the broker was down (more
    than paho's in-flight window: paho writes those itself on the CONNACK, unless held). Once the check
    passes, a handles the messages in order, once each, and writes everything, in order."""
    check = SlowCheck()
    a_got: list[bytes] = []
    b_got: list[bytes] = []
    url = parse_broker_url(broker.url)
    birth = Message("hold/a/status", b'{"online": true}')  # not retained: each one seen live
    a = MqttBus(url, client_id="hold-a", verify=check, birth=birth, reconnect_delay=(1, 1))
    b = MqttBus(url, client_id="hold-b", reconnect_delay=(1, 1))
    a.subscribe("hold/a/in", lambda m: a_got.append(m.payload))
    b.subscribe("hold/b/in", lambda m: b_got.append(m.payload))
    app = AppClient(broker, ["hold/a/out", "hold/a/status"], client_id="hold-app")
    a.connect()
    b.connect()
    away = 300

    def seen(topic: str) -> list[dict[str, int]]:
        with app.cond:
            return [e for t, e in app.events if t == topic]

    try:
        app.wait(lambda ev: len(ev) == 1)  # a's birth
        check.slow = True
        broker.stop()
        assert until(lambda: not a.connected and not app.connected.is_set(), 10)
        for n in range(away):
            a.publish("hold/a/out", b'{"n": %d}' % n)
        broker.start()
        assert check.checking.wait(15), "a's new connection is being checked"
        assert app.connected.wait(15)
        for n in range(5):
            app.send("hold/a/in", b"%d" % n)
        a.publish("hold/a/out", b'{"n": %d}' % away)
        assert until(lambda: b.connects == 2, 15)
        app.send("hold/b/in", b"b-1")
        assert until(lambda: b_got == [b"b-1"], 5), "b is served while a is checked"
        time.sleep(0.5)
        assert a_got == [] and not a.connected
        assert len(seen("hold/a/status")) == 1, "no birth yet"
        assert seen("hold/a/out") == [], "nothing written while held"
        check.release.set()
        assert until(lambda: a_got == [b"%d" % n for n in range(5)], 10), a_got
        app.wait(lambda _ev: len(seen("hold/a/out")) >= away + 1 and len(seen("hold/a/status")) == 2)
        assert [e["n"] for e in seen("hold/a/out")] == list(range(away + 1))
        assert a.connected and a.connects == 2
        time.sleep(0.3)
        assert a_got == [b"%d" % n for n in range(5)]  # each once
    finally:
        check.release.set()
        app.close()
        a.close()
        b.close()


class Blackhole:
    """A listening socket on `port` whose accept queue is full: a client's SYNs are dropped, and its connect
    waits for paho's connect timeout, as to a broker behind a broken network."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", port))
        self.sock.listen(0)
        self.fill: list[socket.socket] = []
        for _ in range(3):  # queued unaccepted: the queue is full
            filler = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            filler.setblocking(False)
            filler.connect_ex(("127.0.0.1", port))
            self.fill.append(filler)

    def close(self) -> None:
        for s in [*self.fill, self.sock]:
            s.close()


def test_a_broker_that_drops_packets_stalls_no_other_brokers_reconnection(tmp_path: Path) -> None:
    """Broker A goes down behind a broken network (each connection attempt waits out paho's 5 s connect
    timeout) while broker B restarts: B's client is back within seconds. Connection attempts run on a few
    helper threads; with one attempt per broker at a time, A's twelve clients do not keep them all waiting
    (they did: twelve 5 s attempts in a queue of four helpers, B's client waited 15 s and more)."""
    a = Mosquitto(tmp_path / "a")
    b = Mosquitto(tmp_path / "b")
    a.start()
    b.start()
    on_a = [MqttBus(parse_broker_url(a.url), client_id=f"dark-{i}", reconnect_delay=(1, 1)) for i in range(12)]
    on_b = MqttBus(parse_broker_url(b.url), client_id="lit", reconnect_delay=(1, 1))
    hole: Blackhole | None = None
    try:
        for bus in [*on_a, on_b]:
            bus.connect()
        a.stop()
        hole = Blackhole(a.port)
        assert until(lambda: not any(bus.connected for bus in on_a), 10)
        time.sleep(3)  # A's clients are trying now, each attempt hanging
        b.restart()
        start = time.monotonic()
        assert until(lambda: on_b.connects == 2, 30)
        took = time.monotonic() - start
        assert took < 8, f"B's client came back after {took:.1f} s"
        hole.close()
        hole = None
        a.start()
        assert until(lambda: all(bus.connects == 2 for bus in on_a), 30), [bus.connects for bus in on_a]
    finally:
        if hole is not None:
            hole.close()
        for bus in [*on_a, on_b]:
            bus.close()
        a.stop()
        b.stop()


def test_a_plain_acknowledgement_is_read_without_pahos_decoder(broker: Mosquitto) -> None:
    """paho's decoder makes two reason codes and a property set for each PUBACK, about half of the serving
    thread's time per acknowledgement, and a fleet's events are acknowledged a thousand times a second: a plain
    one (the message id, success) is read without it, and still completes its message (`flush`). (A refusal,
    an ACL's reason code, still goes through paho's decoder: test_newuser_fleet.py sees it reported.)"""
    from paho.mqtt import _packet

    decoded = [0]
    decode = _packet.decode_puback

    def counting(*args: object) -> object:
        decoded[0] += 1
        return decode(*args)  # type: ignore[arg-type]

    bus = MqttBus(parse_broker_url(broker.url), client_id="acks-plain")
    app = AppClient(broker, ["acks/#"])
    _packet.decode_puback = counting  # type: ignore[assignment]
    try:
        bus.connect()
        for n in range(50):
            bus.publish(f"acks/{n % 3}", str(n).encode())
        assert bus.flush(10.0), "every message acknowledged"
        assert until(lambda: len(app.events) == 50, 10.0), len(app.events)
        assert decoded[0] == 0, f"paho's decoder read {decoded[0]} of 50 plain acknowledgements"
    finally:
        _packet.decode_puback = decode
        bus.close()
        app.close()


def test_an_acknowledgement_of_a_message_nobody_subscribes_to_is_read_without_pahos_decoder(broker: Mosquitto) -> None:
    """An MQTT 5 broker acknowledges a message that matched no subscription with the success code "no matching
    subscribers" (0x10): an edge node's WoT copy of each event, which often has no consumer, half of its
    acknowledgements. Read as the plain one is (paho's decoder cost the serving thread about a tenth of its
    time per query answered); the message is still completed (`flush`) and nothing is reported refused."""
    from paho.mqtt import _packet

    decoded = [0]
    decode = _packet.decode_puback

    def counting(*args: object) -> object:
        decoded[0] += 1
        return decode(*args)  # type: ignore[arg-type]

    bus = MqttBus(parse_broker_url(broker.url), client_id="acks-unheard")
    _packet.decode_puback = counting  # type: ignore[assignment]
    try:
        bus.connect()
        for n in range(50):
            bus.publish(f"unheard/{n % 3}", str(n).encode())
        assert bus.flush(10.0), "every message acknowledged"
        assert decoded[0] == 0, f"paho's decoder read {decoded[0]} of 50 acknowledgements"
        assert bus.refused is None
    finally:
        _packet.decode_puback = decode
        bus.close()


def test_an_event_and_its_wot_copy_go_out_in_one_send(broker: Mosquitto) -> None:
    """Each event an edge node publishes has a WoT copy: written one after the other, they cost the broker two
    wake-ups and the node two system calls and two reads of acknowledgements. Written together, in one send
    (`MqttBus.batch`); both arrive, the envelope first, and both are acknowledged (`flush`). An event published
    from the serving thread itself, or on a bus the loop does not serve, is not held back (the unit tests of
    the WoT topics cover the copy's content)."""
    from td2adaptor.model.events import Kind
    from td2adaptor.runtime.bus.thingbus import ThingBus
    from td2adaptor.runtime.events import encode, envelope
    from tests.runtime.rb1 import rb1_catalog

    robot = "one_send"
    catalog = rb1_catalog()
    spec = catalog.find(Kind.STATE, "gotoRun")
    bus = MqttBus(parse_broker_url(broker.url), client_id="one-send")
    thing = ThingBus(bus, catalog, robot)
    app = AppClient(broker, [f"td2adaptor/{robot}/#"])
    try:
        thing.connect()
        assert bus.flush(10.0)
        client: Any = bus._client
        sends: list[tuple[int, str]] = []
        send = client._sock_send

        def counting(data: bytes) -> int:
            sends.append((len(data), threading.current_thread().name))
            return int(send(data))

        client._sock_send = counting
        for n in range(5):
            payload = {"state": "running", "result": "ok", "terminal": False}
            event = envelope(
                Kind.STATE, robot=robot, source="t", payload=payload, affordance="gotoRun", correlation=f"c{n}"
            )
            thing.publish_event(spec.topic(robot), encode(event), event)
        assert bus.flush(10.0), "every message acknowledged"
        assert until(lambda: len(app.events) == 10, 10.0), app.events
        assert len(sends) <= 5, f"{len(sends)} sends for 5 events and their WoT copies: {sends}"
        topics = [topic for topic, _ in app.events]
        assert topics[0::2] == [spec.topic(robot)] * 5 and all("wot-thing" in t for t in topics[1::2]), topics
        assert [e.get("correlation", e.get("correlationId")) for _, e in app.events] == [
            c for n in range(5) for c in (f"c{n}", f"c{n}")
        ]
        # what is written together counts for paho's keepalive as paho's own writes do (else a connection
        # that only publishes sends a PINGREQ every keepalive period for nothing)
        client._last_msg_out = 0.0
        thing.publish_event(spec.topic(robot), encode(event), event)
        assert bus.flush(10.0)
        assert client._last_msg_out > 0.0
    finally:
        thing.close()
        app.close()
