"""Property events per ROS message (`property_mode: message`), throttled per property (`property_interval`).

The sampling mode (engine.py `_properties`) reads every property each `property_period` and publishes what
changed. In message mode each message a subscribed property receives becomes one property event instead,
through the generated component's per-message callback (`on_<property>`, the port's `watch_property`):

* the callback runs on the ROS executor's thread and only queues the message (no conversion there);
* on ROS 2 the callback gets the message serialized, as the subscription took it (`on_<property>_serialized`,
  the port's `watch_property_serialized`): no message object is made at all;
* one publishing thread per process (`Pump`, shared by every robot the process serves) converts each message
  once (`plain`, or for serialized messages the type's compiled CDR decoder, cdr.py: the values
  `genport.to_plain` gives), encodes it once and splices that text into the event envelope and the WoT form,
  and publishes both, in one send on the robot's connection as `ThingBus` does: the same event, byte for
  byte, as the engine's own `encode(envelope(...))` and `ThingBus` would give, at `property_qos`;
* on MQTT 5 each robot's streams publish on the robot's own connection, written to its socket at once by the
  publishing thread (mqttloop.py): the connection asks for no-local, so the broker does not send the values back
  to the node (whose command filters match their topics), as it did while they had a connection of their own;
  on MQTT 3.1.1 (no such option) they publish on a connection of their own that the publishing thread serves
  itself (drivenbus.py), and when the broker will not take that connection, on the robot's own;
* the rules of property events hold: retained, and only when the value changed (a message equal to the last
  one published for its property is no event);
* `property_interval` > 0: at most one event per property and interval, the latest message wins, and the
  last message is never withheld: a message that arrives within the interval is published when it ends
  (unless a newer one replaced it by then);
* `property_interval` 0: every message, in the order received; when the publishing thread falls behind by
  more than `BACKLOG` messages, the oldest queued are dropped (counted in the engine's `dropped.property`
  statistic, logged at most once a minute), so memory stays bounded.
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import json
import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any

from td2adaptor.model import Model
from td2adaptor.model.events import EventSpec, Kind
from td2adaptor.model.wot import wot_topic
from td2adaptor.runtime.bus.bus import Bus, BusError
from td2adaptor.runtime.bus.thingbus import ThingBus
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.events import new_id, now_rfc3339
from td2adaptor.runtime.ros.cdr import message_class, plain_reader
from td2adaptor.runtime.ros.genport import to_plain
from td2adaptor.runtime.ros.port import RobotPort
from td2adaptor.runtime.ros.words import describe

if TYPE_CHECKING:
    from td2adaptor.runtime.bus.drivenbus import DrivenBus

log = logging.getLogger("td2adaptor.runtime")

#: queued messages (all properties of the process) beyond which the oldest are dropped in per-message mode
BACKLOG = 20_000
#: seconds between two services of the stream connections (acknowledgements, keep-alive) by the publishing thread
SERVE = 0.01

_ENCODER = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, allow_nan=False)
_LATEST = object()  # a queue entry meaning "the property's latest message" (throttled properties)
_fields: dict[type, tuple[str, ...]] = {}


def plain(value: Any) -> Any:
    """`genport.to_plain(value)`, faster for ROS 2 messages and numeric arrays (a 720-range scan)."""
    kind = type(value)
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is int or kind is str or kind is bool or value is None:
        return value
    names = _fields.get(kind)
    if names is None:
        get = getattr(value, "get_fields_and_field_types", None)
        if not callable(get):
            return _sequence(value)
        names = _fields[kind] = tuple(get())
    return {name: plain(getattr(value, name)) for name in names}


def _sequence(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray, Mapping)):
        return to_plain(value)
    tolist = getattr(value, "tolist", None)
    if callable(tolist):
        value = tolist()  # array.array and numpy arrays: Python numbers at C speed
    if isinstance(value, (list, tuple)):
        if all(type(v) is float for v in value):
            return [v if v - v == 0.0 else None for v in value]  # NaN and infinities are no JSON: None
        return [plain(v) for v in value]
    return to_plain(value)


class _Slot:
    """One property of one robot: its topics, envelope text around the value, and its throttle state."""

    __slots__ = (
        "outbox",
        "spec",
        "name",
        "topic",
        "wot",
        "head",
        "middle",
        "interval",
        "last_text",
        "last_time",
        "latest",
        "scheduled",
        "seen",
        "remove",
        "closed",
        "convert",
        "qos",
        "out",
        "bus",
    )

    def __init__(self, outbox: Outbox, spec: EventSpec) -> None:
        config = outbox.config
        self.outbox = outbox  # the robot's: its bus, its configuration, its counts
        self.spec = spec
        self.name = spec.affordance or ""
        self.topic = spec.topic(config.robot, config.topic_root)
        self.wot = wot_topic(spec, config.robot, config.topic_root) if isinstance(outbox.bus, ThingBus) else None
        self.bus = _plain_bus(outbox.bus)  # the WoT form is published beside the envelope here, not by ThingBus
        text = _ENCODER.encode
        kind, robot = text(Kind.PROPERTY.value), text(config.robot)
        self.head = f'{{"type":{kind},"affordance":{text(self.name)},"robot":{robot},"id":"'
        self.middle = f'","source":{text(config.event_source)},"payload":'
        self.interval = config.property_interval
        self.qos = config.property_qos
        self.out: DrivenBus | None = None  # the robot's stream connection, when it has one (publishing thread)
        self.last_text: str | None = None
        self.last_time = -math.inf
        self.latest: Any = None
        self.scheduled = False
        self.seen = False
        self.remove: Callable[[], None] | None = None
        self.closed = False
        self.convert: Callable[[Any], Any] = plain  # a message (or its serialized bytes) → its plain value

    def emit(self, value: Any) -> None:
        """Publish `value` (already plain) unless it equals the last value published (publishing thread)."""
        text = _ENCODER.encode(value)
        if text == self.last_text:
            return
        self.last_text = text
        event = f'{self.head}{new_id()}","time":"{now_rfc3339()}{self.middle}{text}}}'
        bus = self.out or self.bus
        together: Callable[[], AbstractContextManager[Any]] = getattr(bus, "batch", contextlib.nullcontext)
        try:  # the envelope and the WoT form, without parsing the event again, in one send (`MqttBus.batch`)
            with together():
                bus.publish(self.topic, event.encode("utf-8"), retain=True, qos=self.qos)
                if self.wot is not None:
                    bus.publish(self.wot, text.encode("utf-8"), retain=True, qos=self.qos)
        except (BusError, ValueError) as exc:
            log.error("could not publish a property event: %s", exc)
            return
        self.outbox.count("out.property")


class Pump:
    """The process's publishing thread for per-message property events (shared by every robot it serves)."""

    _shared: Pump | None = None
    _shared_lock = threading.Lock()

    def __init__(self) -> None:
        self.cond = threading.Condition(threading.Lock())
        self._ready: deque[tuple[_Slot, Any]] = deque()
        self._timers: list[tuple[float, int, _Slot]] = []
        self._order = itertools.count()
        self._idle = False
        self._users = 0
        self._thread: threading.Thread | None = None
        self._dropped = 0
        self._warned = -math.inf
        self._buses: list[DrivenBus] = []  # the robots' stream connections, served by the publishing thread
        self._closing: list[tuple[DrivenBus, threading.Event]] = []
        self._served = -math.inf

    # -- the process's pump ---------------------------------------------------------------------------------

    @classmethod
    def acquire(cls) -> Pump:
        with cls._shared_lock:
            if cls._shared is None:
                cls._shared = Pump()
            pump = cls._shared
            with pump.cond:
                pump._users += 1
                if pump._thread is None:
                    pump._thread = threading.Thread(target=pump._run, name="td2adaptor-properties", daemon=True)
                    pump._thread.start()
            return pump

    def release(self) -> None:
        with Pump._shared_lock:
            with self.cond:
                self._users -= 1
                if self._users > 0:
                    return
                thread, self._thread = self._thread, None
                self.cond.notify()
            if Pump._shared is self:
                Pump._shared = None
        if thread is not None and thread is not threading.current_thread():
            thread.join(5.0)

    def attach(self, bus: DrivenBus) -> None:
        """Serve `bus` (connected) from the publishing thread, which from now on is the only one to touch it."""
        with self.cond:
            self._buses.append(bus)

    def detach(self, bus: DrivenBus) -> None:
        """Stop serving `bus`: the publishing thread sends what is unacknowledged and closes it (waited for)."""
        done = threading.Event()
        with self.cond:
            if bus in self._buses:
                self._buses.remove(bus)
            running = self._thread is not None and self._thread is not threading.current_thread()
            if running:
                self._closing.append((bus, done))
                if self._idle:
                    self._idle = False
                    self.cond.notify()
        if not running:
            _close(bus)
        elif not done.wait(5.0):
            log.warning("property streams: the publishing thread did not close a stream connection within 5 s")

    # -- from the ROS side ----------------------------------------------------------------------------------

    def put(self, slot: _Slot, message: Any) -> None:
        """A message of `slot`'s property (the ROS executor's thread: no conversion here)."""
        with self.cond:
            slot.seen = True
            if slot.interval <= 0:
                if len(self._ready) >= BACKLOG:
                    old, _ = self._ready.popleft()
                    self._dropped += 1
                    old.outbox.count("dropped.property")
                self._ready.append((slot, message))
            else:
                slot.latest = message
                if slot.scheduled:
                    return  # the pending event will carry this message: the latest wins
                slot.scheduled = True
                due = slot.last_time + slot.interval
                if due <= time.monotonic():
                    self._ready.append((slot, _LATEST))
                else:
                    heapq.heappush(self._timers, (due, next(self._order), slot))
                    if self._timers[0][2] is not slot:
                        return  # an earlier timer ends the publishing thread's wait anyway: no wake for this one
            if self._idle:
                self._idle = False
                self.cond.notify()

    def initial(self, slot: _Slot, value: Any) -> None:
        """The property's value when the robot started being served, unless a message came since."""
        with self.cond:
            if slot.seen:
                return
            slot.seen = True
            self._ready.append((slot, _Value(value)))
            if self._idle:
                self._idle = False
                self.cond.notify()

    # -- the publishing thread ------------------------------------------------------------------------------

    def _take(self) -> list[tuple[_Slot, Any]] | None:
        """The messages to publish ([] when only the stream connections are due a service); None: stop."""
        with self.cond:
            waited = False
            while self._thread is threading.current_thread():
                now = time.monotonic()
                while self._timers and self._timers[0][0] <= now:
                    self._ready.append((heapq.heappop(self._timers)[2], _LATEST))
                if self._ready:
                    batch = list(self._ready)
                    self._ready.clear()
                    for i, (slot, message) in enumerate(batch):
                        if message is _LATEST:  # claim the throttled property's latest message now
                            batch[i] = (slot, slot.latest)
                            slot.latest, slot.scheduled, slot.last_time = None, False, now
                    return batch
                if self._closing or (waited and self._buses):
                    return []
                self._idle = True
                wait = self._timers[0][0] - now if self._timers else None
                if self._buses:  # keep-alive and acknowledgements while idle too
                    wait = 1.0 if wait is None else min(wait, 1.0)
                self.cond.wait(wait)
                self._idle = False
                waited = True
            return None

    def _serve(self, final: bool = False) -> None:
        """Close the detached stream connections and serve the others (at most every SERVE s; `final`: close
        all, the thread ends)."""
        now = time.monotonic()
        with self.cond:
            closing, self._closing = self._closing, []
            if final:
                closing += [(bus, threading.Event()) for bus in self._buses]
                self._buses.clear()
            due = now - self._served >= SERVE
            buses = list(self._buses) if due else []
        for bus, done in closing:
            _close(bus)
            done.set()
        if not due or not buses:
            return
        self._served = now
        from td2adaptor.runtime.bus.drivenbus import serve  # only with stream connections, which imported it

        try:
            serve(buses)
        except Exception as exc:  # noqa: BLE001 - a bug here costs acknowledgements, not the publishing thread
            log.warning("property streams: serving the stream connections failed: %s", describe(exc))

    def _run(self) -> None:
        complained: dict[str, float] = {}
        while True:
            batch = self._take()
            if batch is None:
                self._serve(final=True)
                return
            for slot, message in batch:
                if slot.closed:
                    continue
                try:
                    slot.emit(message.value if isinstance(message, _Value) else slot.convert(message))
                except Exception as exc:  # a message that cannot become JSON costs its event, not the stream
                    if time.monotonic() - complained.get(slot.name, -math.inf) > 60:
                        complained[slot.name] = time.monotonic()
                        log.warning("property %s: a message could not be published: %s", slot.name, describe(exc))
            if self._dropped and time.monotonic() - self._warned > 60:
                self._warned = time.monotonic()
                log.warning(
                    "property events: %d messages dropped so far, the node cannot publish them as fast as they "
                    "come (set property_interval to throttle them)",
                    self._dropped,
                )
            self._serve()


def _plain_bus(bus: Bus) -> Bus:
    """The robot's bus without its WoT adapter (ThingBus), which the streams do the work of themselves."""
    return bus.bus if isinstance(bus, ThingBus) else bus


def _no_echo(bus: Bus) -> bool:
    """Whether the broker sends none of what `bus` publishes back to it (MQTT 5's no-local, which the node's
    connections ask for). Its command filters match the topics of its property values (envelope and WoT form):
    published on a connection of their own, the broker sent each value back to the node twice (the envelope at
    QoS 1, acknowledged), for the serving thread to read and drop, 200 a second for a fleet of 100 RB-1s;
    published on the robot's connection, none comes back. A publish on it is written at once by the publishing
    thread (mqttloop.py), and its acknowledgement is read by the serving thread instead of this one."""
    from td2adaptor.runtime.bus.mqttbus import MqttBus

    return isinstance(bus, MqttBus) and bus.no_local and bus.mqtt_version == "5"


def _close(bus: DrivenBus) -> None:
    """Send what is unacknowledged (at most 1 s) and disconnect."""
    try:
        bus.flush(1.0)
        bus.close()
    except Exception as exc:  # noqa: BLE001 - closing: the broker drops the connection anyway
        log.debug("closing a stream connection: %s", describe(exc))


class _Value:
    """A value already converted (the property's latest value when streaming started)."""

    __slots__ = ("value",)

    def __init__(self, value: Any) -> None:
        self.value = value


class PropertyStreams:
    """One robot's properties in message mode: its callbacks on the port, fed to the process's `Pump`, its
    events published on the bus of its `outbox` (and counted there)."""

    def __init__(self, outbox: Outbox, port: RobotPort, model: Model, specs: list[EventSpec]) -> None:
        self.outbox = outbox
        self.port = port
        self.model = model
        self.specs = specs
        self.slots: list[_Slot] = []
        self.pump: Pump | None = None
        self.out: DrivenBus | None = None

    def start(self) -> None:
        port: Any = self.port  # watch_property is no part of RobotPort: streams() checked it is there
        self.out = self._connection()
        self.pump = pump = Pump.acquire()
        if self.out is not None:
            pump.attach(self.out)
        for spec in self.specs:
            slot = _Slot(self.outbox, spec)
            slot.out = self.out
            slot.remove = self._watch_serialized(slot, pump)
            if slot.remove is None:
                slot.remove = port.watch_property(spec.component or "", slot.name, lambda m, s=slot: pump.put(s, m))
            self.slots.append(slot)
        for slot in self.slots:  # a message that came before: its value, unless a newer one already did
            try:
                value = port.read_property(slot.spec.component or "", slot.name, 0.001)
            except Exception:  # noqa: BLE001 - NoValue, mostly: the first message will be the first event
                continue
            pump.initial(slot, value)

    def _connection(self) -> DrivenBus | None:
        """The robot's own connection for its streams (drivenbus.py), beside its bus; None: the streams go
        through the robot's bus: not on MQTT, a bus whose subscriptions ask for no-local (its own values do not
        come back to it, see `_no_echo`), or the broker would not take a second connection."""
        from td2adaptor.runtime.bus.drivenbus import DrivenBus, twin
        from td2adaptor.runtime.bus.mqttbus import MqttBus

        inner = _plain_bus(self.outbox.bus)
        if not isinstance(inner, MqttBus) or isinstance(inner, DrivenBus):
            return None
        if _no_echo(inner):
            return None  # the robot's own connection: the broker sends none of the values back to the node
        out = twin(inner)
        try:
            out.connect()
        except BusError as exc:
            log.warning(
                "robot %s: no connection of its own for the property streams, they share the robot's: %s",
                self.outbox.config.robot,
                exc,
            )
            return None
        return out

    def _watch_serialized(self, slot: _Slot, pump: Pump) -> Callable[[], None] | None:
        """Watch `slot`'s messages serialized, read by the type's CDR decoder (None: the port cannot)."""
        watch = getattr(self.port, "watch_property_serialized", None)
        if not callable(watch):
            return None
        component = self.model.component(slot.spec.component or "")
        type_name = next((t.type_name for t in component.topics if t.name == slot.name), "")
        cls = message_class(type_name)
        if cls is None:
            return None
        slot.convert = plain_reader(cls)
        remove: Callable[[], None] | None = watch(slot.spec.component or "", slot.name, lambda d: pump.put(slot, d))
        if remove is None:
            slot.convert = plain
        return remove

    def stop(self) -> None:
        for slot in self.slots:
            slot.closed = True
            if slot.remove is not None:
                try:
                    slot.remove()
                except Exception:  # noqa: BLE001 - stopping: the callback goes with the node anyway
                    pass
        if self.pump is not None:
            if self.out is not None:
                self.pump.detach(self.out)
            self.pump.release()
            self.pump = None
        self.out = None


def streams(outbox: Outbox, *, port: RobotPort, model: Model, specs: list[EventSpec]) -> PropertyStreams | None:
    """Message-mode streams of `specs` when the robot's port can watch properties, else None (sampled)."""
    if not callable(getattr(port, "watch_property", None)):
        log.warning(
            "robot %s: its port cannot relay every message (property_mode message): properties are sampled "
            "every property_period instead",
            outbox.config.robot,
        )
        return None
    return PropertyStreams(outbox, port, model, specs)
