"""The event bus as the engine sees it: publish, subscribe with MQTT wildcards, retained messages, a will.

Two implementations share these semantics: `localbus.LocalBus` (in-process) and `mqttbus.MqttBus` (paho-mqtt
against a real broker). Delivery is at least once (QoS 1) and ordered per topic; handlers run on the bus's
own thread and must return quickly (the engine only queues the message). A subscription at QoS 0 is at most
once: what arrives while the client is away is not kept for it (the WoT command topics, whose messages carry
no time by which a stale one could be told apart, see `thingbus`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol


class BusError(Exception):
    """The bus could not connect or was refused; the message says why in terms a user can act on."""


@dataclass(frozen=True)
class Message:
    """A message; `retain` as its publisher set it, also when it reaches a client already subscribed (MQTT 5
    retain-as-published; MQTT 3.1.1 cannot: there only a retained message handed to a new subscription is
    flagged), and on the empty retained message that clears a topic."""

    topic: str
    payload: bytes
    retain: bool = False
    #: the topic it arrived on, when an adapter hands it on under another (a WoT message, wrapped into the
    #: envelope event of `topic` by thingbus.py): what an answer names as where the message came from
    origin: str | None = None
    #: (a QoS 1 message to a subscription made with `acks`) acknowledges it to the broker: call it once, from any
    #: thread, when the message is taken (the engine: admitted, or answered); a message never acknowledged is
    #: delivered again to the next connection of the client's session (this process's after a reconnection, or
    #: the next process to connect with the same client id)
    ack: Callable[[], None] | None = field(default=None, compare=False, repr=False)


Handler = Callable[[Message], None]


def when_flushed(bus: object, then: Callable[[], None]) -> None:
    """`then()` once the broker has everything `bus` published so far, without waiting for it: the bus's own
    `when_flushed` (MqttBus: on its serving thread, once the acknowledgements came), or at once on a bus that
    has none (one whose publish is delivered when it returns)."""
    flushed = getattr(bus, "when_flushed", None)
    if flushed is None:
        then()
    else:
        flushed(then)


def round_trip(bus: object, then: Callable[[bool], None]) -> None:
    """`then(True)` once the broker answered a request `bus` sends now, `then(False)` if its connection is lost
    first (MqttBus `round_trip`), or `then(True)` at once on a bus whose session nobody can take over (no such
    method: the in-process broker)."""
    trip = getattr(bus, "round_trip", None)
    if trip is None:
        then(True)
    else:
        trip(then)


class Bus(Protocol):
    def connect(self) -> None:
        """Connect (or attach to the local broker); raises `BusError` with a clear message on failure."""
        ...

    def subscribe(self, pattern: str, handler: Handler, *, qos: int = 1, acks: bool = False) -> None:
        """Receive messages on `pattern` (`+` one level, `#` the rest), also after reconnects; `qos` 0: not
        what was published while this client was away (the broker does not queue it for the session). `acks`:
        the handler acknowledges each QoS 1 message itself (`Message.ack`), else the bus does once the handlers
        returned; the broker's acknowledgements go in the order the messages came (MQTT asks so)."""
        ...

    def publish(self, topic: str, payload: bytes, *, retain: bool = False, qos: int = 1) -> None:
        """Send with QoS 1: queued while disconnected and sent after reconnecting. `qos` 0 (property events
        when `property_qos` says so): at most once, not acknowledged (`flush` does not wait for it) and dropped
        while disconnected; a subscriber receives it at QoS 0 whatever QoS it subscribed with."""
        ...

    def flush(self, timeout: float) -> bool:
        """Wait until everything published so far is acknowledged; False on timeout."""
        ...

    @property
    def connected(self) -> bool:
        """Whether a broker can acknowledge now (a local bus always can): a node stopping while its broker is
        gone does not wait for acknowledgements that cannot come."""
        ...

    def close(self) -> None:
        """Disconnect cleanly (the will is not published)."""
        ...


def topic_matches(pattern: str, topic: str) -> bool:
    """MQTT topic filter matching; `$`-topics only match filters that start with `$` too."""
    if topic.startswith("$") and not pattern.startswith("$"):
        return False
    p_levels = pattern.split("/")
    t_levels = topic.split("/")
    for i, p in enumerate(p_levels):
        if p == "#":
            return True
        if i >= len(t_levels):
            return False
        if p != "+" and p != t_levels[i]:
            return False
    return len(p_levels) == len(t_levels)


def valid_filter(pattern: str) -> bool:
    """Whether `pattern` is a well-formed MQTT topic filter."""
    if not pattern or "\x00" in pattern:
        return False
    levels = pattern.split("/")
    for i, level in enumerate(levels):
        if "#" in level and (level != "#" or i != len(levels) - 1):
            return False
        if "+" in level and level != "+":
            return False
    return True


def valid_topic(topic: str) -> bool:
    """Whether `topic` can be published to (no wildcards)."""
    return bool(topic) and "\x00" not in topic and "+" not in topic and "#" not in topic


def check_qos(qos: int) -> None:
    """Refuse a QoS the node does not use: 1, and 0 for property events (`property_qos`)."""
    if qos not in (0, 1):
        raise BusError(f"QoS {qos} is not used here (0 or 1)")
