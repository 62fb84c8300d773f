"""An in-process bus with the MQTT semantics the engine relies on, for single-process use, demos and tests.

* sessions by client id survive a disconnect (like `clean_start=False`): their subscriptions stay and
  messages published meanwhile are queued and delivered on reconnect (not those only QoS 0 subscriptions
  match, as mosquitto by default);
* each client has one delivery thread, so messages arrive in publish order (per topic and overall);
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
from collections.abc import Sequence
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
        self._thread: threading.Thread | None = None
        self._stop = False
        self._busy = False

    def connect(self) -> None:
        if self._session is not None:
            return
        self._session = self.broker.attach(self.client_id, clean_start=self.clean_start)
        self._stop = False
        self._thread = threading.Thread(target=self._deliver, name=f"localbus-{self.client_id}", daemon=True)
        self._thread.start()
        for pattern, _ in self._handlers:
            self.broker.subscribe(self._session, pattern, self._qos[pattern])
        for message in self.announce:
            self.broker.publish(message)
        if self.birth is not None:
            self.broker.publish(self.birth)

    def subscribe(self, pattern: str, handler: Handler, *, qos: int = 1) -> None:
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

    def drain(self, timeout: float) -> bool:
        """Wait until this client has handled everything queued for it (tests)."""
        with self.broker.cond:
            return self.broker.cond.wait_for(
                lambda: self._session is None or (not self._session.queue and not self._busy), timeout
            )

    def _deliver(self) -> None:
        session = self._session
        assert session is not None
        cond = self.broker.cond
        while True:
            with cond:
                cond.wait_for(lambda: self._stop or bool(session.queue))
                if self._stop:
                    return
                msg = session.queue.popleft()
                self._busy = True
                handlers = [h for p, h in self._handlers if topic_matches(p, msg.topic)]
            for handler in handlers:
                for attempt in range(1, self.attempts + 1):
                    try:
                        handler(msg)
                        break
                    except Exception:  # noqa: BLE001 - a handler bug must not stop delivery
                        log.exception("local bus: handler failed on %s (attempt %d)", msg.topic, attempt)
            with cond:
                self._busy = False
                cond.notify_all()

    def _detach(self, will: Message | None) -> None:
        session, self._session = self._session, None
        if session is None:
            return
        with self.broker.cond:
            self._stop = True
            self.broker.cond.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)
        self.broker.detach(session, will)

    def close(self) -> None:
        self._detach(None)

    def crash(self) -> None:
        """Disappear without a clean disconnect: the broker publishes the will (tests, fault injection)."""
        self._detach(self.will)
