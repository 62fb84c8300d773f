"""A robot's connection whose session another client takes over right after the broker accepted it, before the
broker took its subscriptions: two processes claiming one robot at once (node/share.py, owner.py). Real
mosquitto; the other client connects at that very moment (a hook in the test's subclass), which two processes
can only hit by chance.

mosquitto 2.0 closes the taken-over connection without MQTT 5's "Session taken over" reason, so the client sees
only a lost connection. Before, `connect()` waited its whole `connect_timeout` for a SUBACK that could not come
(the share's thread stalled that long), then returned as if connected; the connection's reconnection then took
the session back from the other client, which lost it in turn. Now `connect()` fails at once, saying why, and
nothing of this connection reaches the broker again."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import orjson
import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from td2adaptor.runtime.bus.bus import BusError, Message
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import parse_broker_url
from td2adaptor.runtime.node.owner import probe_bus, read_statuses, taken_by
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, release
from tests.runtime.edge import until

CLIENT_ID = "td2adaptor-rb_07"


class Other:
    """The other process's connection with the robot's session: counts the times it lost it."""

    def __init__(self, broker: Mosquitto) -> None:
        self.connected = threading.Event()
        self.lost = 0
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=CLIENT_ID, protocol=mqtt.MQTTv5)
        self.client.on_connect = lambda *_a: self.connected.set()
        self.client.on_disconnect = self._lost
        props = Properties(PacketTypes.CONNECT)  # type: ignore[no-untyped-call]
        props.SessionExpiryInterval = 3600
        self.client.connect("127.0.0.1", broker.port, 30, clean_start=False, properties=props)
        self.client.loop_start()

    def _lost(self, *_args: Any) -> None:
        self.lost += 1
        self.connected.clear()

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()
        release(self.client)


class TakenOverAtOnce(MqttBus):
    """Its first subscriptions are sent only once the other client has taken its session."""

    broker: Mosquitto
    other: Other | None = None

    def _subscribe(self, client: mqtt.Client, patterns: list[tuple[str, int]]) -> Any:
        if self.other is None:
            self.other = Other(self.broker)
            assert self.other.connected.wait(5)
        return super()._subscribe(client, patterns)


def test_a_connection_taken_over_before_its_subscriptions_fails_at_once_and_leaves_the_session_alone(
    tmp_path: Path,
) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    status = "td2adaptor/rb_07/status"
    bus = TakenOverAtOnce(
        parse_broker_url(broker.url),
        client_id=CLIENT_ID,
        birth=Message(status, b'{"state": "online"}', retain=True),
        connect_timeout=5,
    )
    bus.broker = broker
    bus.subscribe("td2adaptor/rb_07/+/+", lambda _m: None)
    began = time.monotonic()
    try:
        with pytest.raises(BusError) as raised:
            bus.connect()
        took = time.monotonic() - began
        assert took < 2.5, took  # not the connect_timeout's 5 s
        assert "took its session over" in str(raised.value) and CLIENT_ID in str(raised.value), raised.value
        assert "Error" not in str(raised.value)
        other = bus.other
        assert other is not None
        # the session stays the other's: nothing of this client reconnects to take it back
        assert not until(lambda: other.lost > 0, 5), "the other client lost the session"
        # and this client's birth (its `online`) never reached the broker
        reader = AppClient(broker, [status])
        try:
            time.sleep(0.3)  # a retained message comes right after the SUBACK, which the client waited for
            assert not reader.events, reader.events
        finally:
            reader.close()
    finally:
        bus.close()
        if bus.other is not None:
            bus.other.close()
        broker.stop()


def _status(state: str, node: str, pid: int) -> bytes:
    owner = {"host": "vm", "pid": pid, "started": "2026-01-01T00:00:00Z", "node": node}
    return orjson.dumps({"type": "status", "payload": {"state": state, "owner": owner}})


def test_a_connection_whose_session_another_client_took_over_does_not_take_it_back_from_the_robots_new_owner(
    tmp_path: Path,
) -> None:
    """Two processes both passed the share's last look and both connected the robot: the later connection took
    the session over, and mosquitto 2.0 closed the earlier one without saying why. Its reconnection would take
    the session back from the other, then find (its `owned` check) that the other serves the robot and drop,
    its will putting `offline` over the other's `online`: the robot flapped once. Now it asks `owned` before it
    reconnects, and stops serving without touching the session."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    status = "td2adaptor/rb_07/status"
    ours, theirs = _status("online", "aaaa", 1), _status("online", "bbbb", 2)
    bus = MqttBus(
        parse_broker_url(broker.url),
        client_id=CLIENT_ID,
        birth=Message(status, ours, retain=True),
        will=Message(status, _status("offline", "aaaa", 1), retain=True),
        reconnect_delay=(1, 2),
        connect_timeout=5,
    )

    def owned() -> str | None:  # what a robot's status keeper asks (node/status.py StatusKeeper.owned)
        seen = read_statuses(probe_bus(bus.address, bus.security, bus.mqtt_version), [status])
        return taken_by("rb_07", seen.get(status), [ours])

    bus.owned = owned
    refused: list[str] = []
    bus.on_refused = refused.append
    bus.subscribe("td2adaptor/rb_07/+/+", lambda _m: None)
    other: Other | None = None
    try:
        bus.connect()
        other = Other(broker)  # takes the session over
        assert other.connected.wait(5)
        other.client.publish(status, theirs, qos=1, retain=True).wait_for_publish(5)  # the new owner's birth
        assert until(lambda: bool(refused), 10), "this client did not stop serving"
        assert "took its session over" in refused[0] and "process 2 on vm" in refused[0], refused
        assert not until(lambda: other is not None and other.lost > 0, 4), "this client took the session back"
        reader = AppClient(broker, [status])
        try:
            time.sleep(0.3)  # a retained message comes right after the SUBACK, which the client waited for
            assert [e["payload"]["owner"]["node"] for _t, e in reader.events] == ["bbbb"], reader.events
            assert [e["payload"]["state"] for _t, e in reader.events] == ["online"], reader.events
        finally:
            reader.close()
    finally:
        bus.close()
        if other is not None:
            other.close()
        broker.stop()
