"""An MQTT connection served by the thread that publishes on it, for the property streams (streams.py).

A `MqttBus` is served by a network thread (the process's serving loop, mqttloop.py): every publish wakes that
thread to write the message, and the publisher waits for the interpreter lock again behind it. A process that
streams a thousand property events a second would wake it two thousand times a second, and its publishing
thread would spend most of its time waiting (bench/sensor_stream_ros2.py). `DrivenBus` has no network
thread: a publish writes to the socket at once, in the publisher's thread, and that thread calls `step()`
between batches to read what the broker sent (PUBACKs, PINGRESPs), keep the connection alive and reconnect.

Only its owner's thread may publish on it or step it. It publishes only (no subscriptions), on a clean session
with no will: it is a second connection of a robot's node, with the robot's credentials (`twin`). A thread that
owns many (the streams of a fleet's hundred robots) serves them together with `serve`: one `poll` over their
sockets, keep-alive at most every `MISC` seconds, instead of a `select` per connection at every batch.
"""

from __future__ import annotations

import logging
import math
import select
import ssl
import time

import paho.mqtt.client as mqtt
from paho.mqtt.enums import MQTTErrorCode

from td2adaptor.runtime.bus.mqttbus import MqttBus

log = logging.getLogger("td2adaptor.runtime.bus")

#: seconds between two keep-alive checks of a connection served by `serve` (keep-alive periods are many seconds)
MISC = 0.5


class DrivenBus(MqttBus):
    """A publishing MQTT connection without a network thread: its owner's thread publishes and `step`s it."""

    _retry_at = -math.inf  # when `step` may try to reconnect next
    _complained = -math.inf
    _misc_at = -math.inf  # when `serve` checks its keep-alive next

    def _start(self, client: mqtt.Client) -> None:
        """No network thread: publishes write at once (paho does when it has no thread), `step` reads."""

    def _stop(self, client: mqtt.Client) -> None:
        """A normal disconnect, written at once (the broker drops the will)."""
        client.disconnect()

    def _await_connack(self, client: mqtt.Client) -> bool:
        deadline = time.monotonic() + self.connect_timeout
        while not self._connack.is_set():
            left = deadline - time.monotonic()
            if left <= 0 or not self._serve(client, min(left, 0.1)):
                return self._connack.is_set()
        return True

    def _serve(self, client: mqtt.Client, timeout: float) -> bool:
        """Read and write what is due, waiting at most `timeout`; False when the connection is gone."""
        sock = client.socket()
        if sock is None:
            return False
        pending = isinstance(sock, ssl.SSLSocket) and sock.pending() > 0
        want = [sock] if client.want_write() else []
        readable, writable, _ = select.select([sock], want, [], 0 if pending else timeout)
        return self._ready(client, bool(readable) or pending, bool(writable), misc=True)

    def step(self) -> None:
        """Serve the connection once without waiting; reconnect (every `reconnect_delay[1]` s) when it is gone."""
        client = self._client
        if client is None:
            return
        if not self._serve(client, 0.0):
            self._revive(client)

    def _ready(self, client: mqtt.Client, readable: bool, writable: bool, *, misc: bool) -> bool:
        """Read and write what a select found due, and the keep-alive (`misc`); False: the connection is gone."""
        rc = MQTTErrorCode.MQTT_ERR_SUCCESS
        if readable:
            rc = client.loop_read()
        if rc is MQTTErrorCode.MQTT_ERR_SUCCESS and writable:
            rc = client.loop_write()
        if rc is MQTTErrorCode.MQTT_ERR_SUCCESS and misc:
            rc = client.loop_misc()  # keep-alive: a PINGREQ when due, the connection dropped when unanswered
        return rc is MQTTErrorCode.MQTT_ERR_SUCCESS and client.socket() is not None

    def _revive(self, client: mqtt.Client) -> None:
        """Reconnect a connection found gone, at most every `reconnect_delay[1]` seconds."""
        now = time.monotonic()
        if now < self._retry_at:
            return
        self._retry_at = now + self.reconnect_delay[1]
        try:
            client.reconnect()
        except (OSError, ssl.SSLError, ValueError) as exc:
            if now - self._complained > 60:
                self._complained = now
                log.warning("property stream connection to %s: reconnecting failed: %s", self.address, exc)

    def flush(self, timeout: float) -> bool:
        """Serve the connection until every QoS 1 message is acknowledged, at most `timeout` seconds."""
        deadline = time.monotonic() + timeout
        client = self._client
        while client is not None:
            with self._lock:
                if not self._pending:
                    return True
            left = deadline - time.monotonic()
            if left <= 0 or not self._serve(client, min(left, 0.05)):
                break
        with self._lock:
            return not self._pending


def serve(buses: list[DrivenBus]) -> None:
    """Serve `buses` once without waiting, as `step` serves one: a single poll over their sockets reads the
    acknowledgements and finishes partial writes; keep-alive every `MISC` s; the ones found gone reconnect.
    (poll, not select: a fleet's process may hold more than select's 1,024 descriptors.)"""
    if not hasattr(select, "poll"):  # Windows: one select each, as `step`
        for bus in buses:
            bus.step()
        return
    served: dict[int, tuple[DrivenBus, mqtt.Client, bool]] = {}
    poller = select.poll()
    for bus in buses:
        client = bus._client
        if client is None:
            continue
        sock = client.socket()
        if sock is None:
            bus._revive(client)
            continue
        pending = isinstance(sock, ssl.SSLSocket) and sock.pending() > 0  # decrypted already: poll would not say
        served[sock.fileno()] = (bus, client, pending)
        poller.register(sock, select.POLLIN | (select.POLLOUT if client.want_write() else 0))
    events = dict(poller.poll(0)) if served else {}
    now = time.monotonic()
    for fd, (bus, client, pending) in served.items():
        mask = events.get(fd, 0)
        misc = now >= bus._misc_at
        if misc:
            bus._misc_at = now + MISC
        readable = pending or bool(mask & (select.POLLIN | select.POLLERR | select.POLLHUP))
        try:
            if not bus._ready(client, readable, bool(mask & select.POLLOUT), misc=misc):
                bus._revive(client)
        except Exception as exc:  # noqa: BLE001 - one broken connection must not keep the others unserved
            log.warning("property stream connection to %s: serving it failed: %s", bus.address, exc)


def twin(bus: MqttBus) -> DrivenBus:
    """A publishing connection beside `bus`: its broker, credentials, TLS and MQTT version, the client id
    `<client id>-streams`, a clean session and no will (not connected yet)."""
    return DrivenBus(
        bus.address,
        bus.security,
        client_id=f"{bus.client_id}-streams",
        clean_start=True,
        session_expiry=0,
        mqtt_version=bus.mqtt_version,
        keepalive=bus.keepalive,
        connect_timeout=bus.connect_timeout,
        reconnect_delay=bus.reconnect_delay,
    )
