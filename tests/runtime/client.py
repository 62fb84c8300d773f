"""A plain paho client standing in for an application on the bus (independent of the runtime's MqttBus)."""

from __future__ import annotations

import json
import threading
import uuid
from collections.abc import Callable
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

Event = tuple[str, dict[str, Any]]


class AppClient:
    """Subscribes to `patterns` (QoS 1, persistent session) and records every event it receives."""

    def __init__(
        self,
        url: str | Any,
        patterns: list[str],
        *,
        client_id: str | None = None,
        username: str | None = None,
        password: str | None = None,
        mqtt_version: str = "5",
    ) -> None:
        if not isinstance(url, str):  # a test broker: its URL and the MQTT version it speaks
            url, mqtt_version = url.url, url.mqtt_version
        host, port = url.removeprefix("mqtt://").rsplit(":", 1)
        self.events: list[Event] = []
        self.qos: dict[str, set[int]] = {}  # each topic's QoS as delivered (the lower of publish and subscribe)
        self.cond = threading.Condition()
        self.connected = threading.Event()
        self.patterns = patterns
        v5 = mqtt_version == "5"
        self.client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id or f"app-{uuid.uuid4().hex[:8]}",
            protocol=MQTTProtocolVersion.MQTTv5 if v5 else MQTTProtocolVersion.MQTTv311,
            clean_session=None if v5 else False,
        )
        self.client.reconnect_delay_set(1, 2)
        if username:
            self.client.username_pw_set(username, password)
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self.client.on_subscribe = self._on_subscribe
        self.client.on_disconnect = lambda *_: self.connected.clear()
        if v5:
            props = Properties(PacketTypes.CONNECT)  # type: ignore[no-untyped-call]
            props.SessionExpiryInterval = 600
            self.client.connect(host, int(port), 30, clean_start=False, properties=props)
        else:
            self.client.connect(host, int(port), 30)
        self.client.loop_start()
        assert self.connected.wait(10), "test client could not connect"

    def _on_connect(self, client: mqtt.Client, _u: Any, _f: Any, reason: Any, _p: Any) -> None:
        if not reason.is_failure:
            client.subscribe([(p, 1) for p in self.patterns])  # connected once the SUBACK is in

    def _on_subscribe(self, *_args: Any) -> None:
        self.connected.set()

    def _on_message(self, _c: mqtt.Client, _u: Any, msg: mqtt.MQTTMessage) -> None:
        try:
            data = json.loads(msg.payload)
        except ValueError:
            data = {"raw": msg.payload.decode(errors="replace")}
        with self.cond:
            self.events.append((msg.topic, data))
            self.qos.setdefault(msg.topic, set()).add(msg.qos)
            self.cond.notify_all()

    def send(self, topic: str, event: Any, *, while_offline: bool = False) -> None:
        """Publish with QoS 1 and wait for the PUBACK; `while_offline`: if the client is disconnected (a broker
        restart), leave the message to paho, which sends it once reconnected, instead of failing."""
        payload = event if isinstance(event, bytes) else json.dumps(event).encode()
        info = self.client.publish(topic, payload, qos=1)
        if while_offline and info.rc == mqtt.MQTT_ERR_NO_CONN:
            return
        info.wait_for_publish(10)

    def wait(self, predicate: Callable[[list[Event]], bool], timeout: float = 10.0) -> list[Event]:
        with self.cond:
            ok = self.cond.wait_for(lambda: predicate(self.events), timeout)
            assert ok, f"timed out; received {[(t, e.get('payload')) for t, e in self.events][-10:]}"
            return list(self.events)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()
        release(self.client)


def release(client: mqtt.Client) -> None:
    """Drop a stopped client's callbacks, which refer back to their owner: the reference cycle kept the socket
    pair `loop_start()` made open until a garbage collection, whose finalisers closed it in any order and
    sometimes warned of an unclosed socket (an unraisable `ResourceWarning`, an error under the suite's
    `filterwarnings`, seen at the end of a test session). Without the cycle it is closed when the client goes."""
    client.on_connect = client.on_message = client.on_subscribe = client.on_disconnect = None
