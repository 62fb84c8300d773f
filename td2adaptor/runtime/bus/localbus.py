"""An in-process bus with the MQTT semantics the engine relies on, for single-process use, demos and tests.

* sessions by client id survive a disconnect (like `clean_start=False`): their subscriptions stay and
  messages published meanwhile are queued and delivered on reconnect (not those only QoS 0 subscriptions
  match, as mosquitto by default);
* one delivery thread per broker (`td2adaptor-localbus`, while a client is connected) serves every client in
  turn, one message each, so messages arrive in publish order (per topic and overall) and a process of a
  hundred robots on the local bus has one such thread, not a hundred; a handler must return quickly (the
  engine's only hands the message to its loop), as on the MQTT bus;
* a handler that raises gets the message again (at least once, up to `attempts` times);
* retained messages are delivered to new subscriptions; an empty retained payload deletes;
* a message keeps the retain flag it was published with, also for the clients already subscribed (MQTT 5's
  retain-as-published, which `MqttBus` asks for): a command published retained is told from a live one;
* a will is published when a client disappears without `close()` (`crash()`).
"""

from __future__ import annotations

import logging
import threading
import uuid
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from td2adaptor.runtime.bus.bus import BusError, Handler, Message, check_qos, topic_matches, valid_filter, valid_topic

log = logging.getLogger("td2adaptor.runtime.bus")


@dataclass
class _Session:
    client_id: str
    patterns: list[str] = field(default_factory=list)
    qos: dict[str, int] = field(default_factory=dict)
    queue: deque[Message] = field(default_factory=deque)
    attached: bool = False
    dropped: int = 0
    consumer: LocalBus | None = None  # the connected client that handles its messages
    scheduled: bool = False  # in the broker's turn (it has messages for its consumer)
    busy: bool = False  # its consumer's handlers run on a message

    def matches(self, topic: str) -> bool:
        """Whether `topic` is for this session now: a QoS 0 subscription only while it is attached."""
        return any(topic_matches(p, topic) and (self.attached or self.qos.get(p, 1) > 0) for p in self.patterns)


class LocalBroker:
    """The shared hub: sessions, retained messages and the lock that orders every publish."""

    _default: LocalBroker | None = None
    _default_lock = threading.Lock()

    def __init__(self, max_queue: int = 100_000) -> None:
        self.max_queue = max_queue
        self.cond = threading.Condition()
        self._sessions: dict[str, _Session] = {}
        self._retained: dict[str, Message] = {}
        self.published = 0
        self._turn: deque[_Session] = deque()  # sessions with messages for their consumer, in turn
        self._consumers = 0
        self._deliverer: threading.Thread | None = None

    @classmethod
    def default(cls) -> LocalBroker:
        """The process-wide broker behind `--bus local`."""
        with cls._default_lock:
            if cls._default is None:
                cls._default = LocalBroker()
            return cls._default

    def attach(self, client_id: str, *, clean_start: bool) -> _Session:
        with self.cond:
            session = self._sessions.get(client_id)
            if session is not None and session.attached:
                raise BusError(f"client id {client_id!r} is already connected to the local bus")
            if session is None or clean_start:
                session = _Session(client_id)
                self._sessions[client_id] = session
            session.attached = True
            return session

    def detach(self, session: _Session, will: Message | None = None) -> None:
        with self.cond:
            session.attached = False
        if will is not None:
            self.publish(will)

    def subscribe(self, session: _Session, pattern: str, qos: int = 1) -> None:
        with self.cond:
            if pattern not in session.patterns:
                session.patterns.append(pattern)
            session.qos[pattern] = max(qos, session.qos.get(pattern, 0))
            for topic, msg in self._retained.items():
                if topic_matches(pattern, topic):
                    self._enqueue(session, msg)
            self.cond.notify_all()

    def _enqueue(self, session: _Session, msg: Message) -> None:
        if len(session.queue) >= self.max_queue:
            session.queue.popleft()
            session.dropped += 1
            if session.dropped in (1, 10, 100) or session.dropped % 1000 == 0:
                log.warning("local bus: queue of %s is full, %d messages dropped", session.client_id, session.dropped)
        session.queue.append(msg)
        self._schedule(session)

    def _schedule(self, session: _Session) -> None:
        """(under cond) Give `session` a turn if it has a message and a consumer and has no turn yet."""
        if session.consumer is not None and session.queue and not session.scheduled:
            session.scheduled = True
            self._turn.append(session)

    def serve(self, session: _Session, bus: LocalBus) -> None:
        """`bus` handles the messages of `session` from now on (on the broker's delivery thread)."""
        with self.cond:
            session.consumer = bus
            self._consumers += 1
            if self._deliverer is None:
                self._deliverer = threading.Thread(target=self._deliver, name="td2adaptor-localbus", daemon=True)
                self._deliverer.start()
            self._schedule(session)
            self.cond.notify_all()

    def unserve(self, session: _Session) -> None:
        """No more messages for the consumer of `session`; returns once its handlers are done with the current
        one (at once when called from a handler)."""
        with self.cond:
            session.consumer = None
            self._consumers -= 1
            self.cond.notify_all()
            if threading.current_thread() is not self._deliverer:
                self.cond.wait_for(lambda: not session.busy, 5.0)

    def idle(self, session: _Session) -> bool:
        """(under cond) Nothing queued for `session` and no handler running on one of its messages."""
        return not session.queue and not session.busy

    def _deliver(self) -> None:
        """The delivery thread: one message to each session in turn, until no client is connected."""
        cond = self.cond
        while True:
            with cond:
                cond.wait_for(lambda: bool(self._turn) or self._consumers == 0)
                if not self._turn:
                    self._deliverer = None
                    return
                session = self._turn.popleft()
                session.scheduled = False
                bus = session.consumer
                if bus is None or not session.queue:
                    continue
                msg = session.queue.popleft()
                session.busy = True
                handlers = bus.handlers(msg.topic)
            for handler in handlers:
                bus.handle(handler, msg)
            with cond:
                session.busy = False
                self._schedule(session)
                cond.notify_all()

    def publish(self, msg: Message) -> None:
        with self.cond:
            self.published += 1
            if msg.retain:
                if msg.payload:
                    self._retained[msg.topic] = msg
                else:
                    self._retained.pop(msg.topic, None)
            for session in self._sessions.values():
                if session.matches(msg.topic):
                    self._enqueue(session, msg)  # its retain flag as published (an empty clear's too)
            self.cond.notify_all()


class LocalBus:
    """One client of a `LocalBroker` (by default the process-wide one)."""

    def __init__(
        self,
        broker: LocalBroker | None = None,
        client_id: str | None = None,
        *,
        will: Message | None = None,
        birth: Message | None = None,
        announce: Sequence[Message] = (),
        clean_start: bool = False,
        attempts: int = 3,
    ) -> None:
        self.broker = broker or LocalBroker.default()
        self.client_id = client_id or f"local-{uuid.uuid4().hex[:12]}"
        self.will = will
        self.birth = birth
        self.announce = tuple(announce)
        self.clean_start = clean_start
        self.attempts = attempts
        self._handlers: list[tuple[str, Handler]] = []
        self._qos: dict[str, int] = {}
        self._session: _Session | None = None

    def connect(self) -> None:
        if self._session is not None:
            return
        self._session = self.broker.attach(self.client_id, clean_start=self.clean_start)
        self.broker.serve(self._session, self)
        for pattern, _ in self._handlers:
            self.broker.subscribe(self._session, pattern, self._qos[pattern])
        for message in self.announce:
            self.broker.publish(message)
        if self.birth is not None:
            self.broker.publish(self.birth)

    def subscribe(self, pattern: str, handler: Handler, *, qos: int = 1, acks: bool = False) -> None:
        """(`acks`: nothing to acknowledge in process: a message is the handler's once it is delivered)"""
        if not valid_filter(pattern):
            raise BusError(f"invalid topic filter {pattern!r}")
        with self.broker.cond:
            self._handlers.append((pattern, handler))
            self._qos[pattern] = max(qos, self._qos.get(pattern, 0))
        if self._session is not None:
            self.broker.subscribe(self._session, pattern, qos)

    def publish(self, topic: str, payload: bytes, *, retain: bool = False, qos: int = 1) -> None:
        check_qos(qos)
        if not valid_topic(topic):
            raise BusError(f"invalid topic {topic!r}")
        self.broker.publish(Message(topic, bytes(payload), retain))

    def flush(self, timeout: float) -> bool:
        return True  # a local publish is in every subscriber's queue when `publish` returns

    def when_flushed(self, then: Callable[[], None]) -> None:
        """`then()` once everything published so far is acknowledged: at once (see `flush`)."""
        then()

    @property
    def connected(self) -> bool:
        return True

    def drain(self, timeout: float) -> bool:
        """Wait until this client has handled everything queued for it (tests)."""
        with self.broker.cond:
            return self.broker.cond.wait_for(lambda: self._session is None or self.broker.idle(self._session), timeout)

    def handlers(self, topic: str) -> list[Handler]:
        """(under the broker's cond) The handlers of the subscriptions `topic` matches."""
        return [h for p, h in self._handlers if topic_matches(p, topic)]

    def handle(self, handler: Handler, msg: Message) -> None:
        """(the broker's delivery thread) Run `handler` on `msg`: again when it raises, up to `attempts` times."""
        for attempt in range(1, self.attempts + 1):
            try:
                handler(msg)
                return
            except Exception:  # noqa: BLE001 - a handler bug must not stop delivery
                log.exception("local bus: handler failed on %s (attempt %d)", msg.topic, attempt)

    def _detach(self, will: Message | None) -> None:
        session, self._session = self._session, None
        if session is None:
            return
        self.broker.unserve(session)
        self.broker.detach(session, will)

    def close(self) -> None:
        self._detach(None)

    def crash(self) -> None:
        """Disappear without a clean disconnect: the broker publishes the will (tests, fault injection)."""
        self._detach(self.will)
