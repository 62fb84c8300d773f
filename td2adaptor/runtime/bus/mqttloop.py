"""One thread serves every MQTT connection an `MqttBus` opens in the process, with paho's external-loop API.

paho's `loop_start()` gives each client a network thread of its own: a fleet of 100 robots in one process had
100 of them, every publish woke its robot's thread, and under load most of their time went into waiting for
the interpreter lock (docs/performance.md). Here one thread (`td2adaptor-mqtt`) waits on every connection's socket
in one selector and does for each what paho's thread did: it reads what the broker sends (paho calls the bus's
callbacks; its handlers only queue the messages), keeps the connection alive (`loop_misc`) and reconnects a
lost one after paho's back-off (the first wait `reconnect_delay[0]`, doubling up to `reconnect_delay[1]`, from
the start again once a CONNACK accepts it). A publish is written by the publishing thread itself, as paho
does without a network thread, unless the loop is on that connection at that moment: then it wakes the loop
(a socket pair in its selector), which writes it. Nothing that may block runs on the loop's thread: a
reconnection's TCP connect and TLS handshake, and a bus's check of a new connection, run on a few helper
threads (`td2adaptor-mqtt-helper-N`, at most `HELPERS`; one attempt per broker at a time), so that one slow
or unreachable broker never stalls the other connections.

A connection's socket is read and written only under its `Link.io` lock (the loop's steps, a publisher's
write), and taken out of the selector before paho closes it, so the selector never holds a stale descriptor;
a helper reconnects a client only while the loop has no socket of it. A held connection (`Link.hold`, while
the bus checks it) is read but not written: nothing goes to a broker not yet trusted, not even the
acknowledgement of a message.
"""

from __future__ import annotations

import contextlib
import functools
import heapq
import itertools
import logging
import queue
import select
import selectors
import socket
import ssl
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any, Literal

import paho.mqtt.client as mqtt
from paho.mqtt.enums import MQTTErrorCode
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties
from paho.mqtt.reasoncodes import ReasonCode

log = logging.getLogger("td2adaptor.runtime.bus")

#: seconds between two keep-alive checks of every connection (keep-alive periods are whole seconds)
MISC = 0.5
#: threads for what may block (reconnections, checks of new connections)
HELPERS = 4
#: reads of one connection in one turn at most (paho reads one packet a read, or as many as it has in flight):
#: what the broker wrote is read together, also the end of a connection behind a burst of commands (a session
#: taken over while the process stood still, node/share.py), and one busy connection cannot hold the others long
READ_PACKETS = 64
THREAD = "td2adaptor-mqtt"
_OK = MQTTErrorCode.MQTT_ERR_SUCCESS


#: what a plain acknowledgement tells `on_publish` (never changed by it): paho makes both anew for each one
_ACCEPTED = ReasonCode(PacketTypes.PUBACK)
_NO_PROPERTIES = Properties(PacketTypes.PUBACK)  # type: ignore[no-untyped-call]
#: MQTT 5's success codes of a PUBACK without properties, by their byte: "success" and "no matching subscribers"
#: (0x10, what mosquitto answers for an event nobody listens to, as an edge node's WoT copy often is)
_SUCCESSES = {0: _ACCEPTED, 0x10: ReasonCode(PacketTypes.PUBACK, identifier=0x10)}
#: the packets `ServedClient` writes together (paho does nothing once one of them is written): a QoS 1 or 2
#: PUBLISH, a PUBACK; at most this many in one send
_JOINED = frozenset({mqtt.PUBLISH, mqtt.PUBACK})
JOIN_PACKETS = 64


class ServedClient(mqtt.Client):
    """A paho client that writes nothing while `held`: paho writes by itself in one place, on a CONNACK when
    more messages wait than its in-flight window lets out (`loop_write` from inside the read). It reads a plain
    PUBACK (the message id, a success code of `_SUCCESSES`, no properties: what mosquitto sends) without paho's
    decoder, which makes two reason codes and a property set for each, about half of the serving thread's time
    per acknowledgement (a fleet's events are acknowledged a thousand times a second); any other goes to
    paho's."""

    held = False
    #: the threads in a `Link.batch` now: nothing is written until the last one ends its batch (and writes)
    batching: set[int] | frozenset[int] = frozenset()

    def loop_write(self) -> MQTTErrorCode:
        if self.held or self.batching:
            return _OK
        return super().loop_write()

    def _packet_write(self) -> MQTTErrorCode:
        """paho's, but the PUBLISH (QoS 1) and PUBACK packets waiting at the head of the queue go out in one
        send, not one each: an event and its WoT copy (`Link.batch`), or a burst of acknowledgements, cost
        the broker one wake-up and this process one system call (and, as the broker acknowledges them
        together, one read of the serving thread). Anything else is paho's to write, one packet at a time. It
        stops when a thread begins a batch meanwhile: the batch's end writes what waits."""
        out = self._out_packet
        while out and not self.batching:
            joined: list[Any] = []
            while out and len(joined) < JOIN_PACKETS:
                command = out[0]["command"] & 0xF0
                if command not in _JOINED or (command == mqtt.PUBLISH and not out[0]["qos"]):
                    break
                joined.append(out.popleft())
            if not joined:
                return super()._packet_write()
            try:
                written = self._sock_send(b"".join(p["packet"][p["pos"] :] for p in joined))
            except (AttributeError, ValueError):
                out.extendleft(reversed(joined))
                return _OK
            except BlockingIOError:
                out.extendleft(reversed(joined))
                return MQTTErrorCode.MQTT_ERR_AGAIN
            except OSError as err:
                out.extendleft(reversed(joined))
                self._easy_log(mqtt.MQTT_LOG_ERR, "failed to receive on socket: %s", err)
                return MQTTErrorCode.MQTT_ERR_CONN_LOST
            with self._msgtime_mutex:  # paho's keepalive: something was sent (as paho's own write notes)
                self._last_msg_out = mqtt.time_func()
            for i, packet in enumerate(joined):
                step = min(written, packet["to_process"])
                written -= step
                packet["pos"] += step
                packet["to_process"] -= step
                if packet["to_process"]:  # the socket took part of it: the rest when it is writable again
                    out.extendleft(reversed(joined[i:]))
                    return MQTTErrorCode.MQTT_ERR_AGAIN
        return _OK

    def _handle_pubackcomp(self, cmd: Literal["PUBACK", "PUBCOMP"]) -> MQTTErrorCode:
        packet = self._in_packet["packet"]
        if cmd != "PUBACK" or len(packet) not in (2, 3):
            return super()._handle_pubackcomp(cmd)
        reason = _ACCEPTED if len(packet) == 2 else _SUCCESSES.get(packet[2])
        if reason is None or (len(packet) == 3 and self._protocol != mqtt.MQTTv5):
            return super()._handle_pubackcomp(cmd)  # a refusal; or malformed for MQTT 3.1.1: paho refuses it
        mid = packet[0] << 8 | packet[1]
        with self._out_message_mutex:
            if mid in self._out_messages:
                return self._do_on_publish(mid, reason, _NO_PROPERTIES)
        return _OK


class Link:
    """One paho client served by the loop. Its state belongs to the loop's thread; other threads use `start`,
    `close`, and paho's callbacks set here (a publish written at once, or the loop woken to write it)."""

    def __init__(self, loop: MqttLoop, client: mqtt.Client, reconnect_delay: tuple[int, int], name: str) -> None:
        self.loop = loop
        self.client = client
        self.name = name  # for the log
        self.min_delay, self.max_delay = reconnect_delay
        self.delay: float | None = None  # the last wait before a reconnection; None: connected since
        self.sock: Any = None  # the socket registered in the selector
        self.writing = False  # registered for writability too (a write would have blocked)
        self._held = False  # write nothing (the bus checks this connection)
        self.closing = False  # never reconnect; forget once the socket is gone
        self.away = False  # no socket: waiting to reconnect, or reconnecting on a helper
        self.trying = False  # a helper is reconnecting it
        #: (helper thread) asked before each reconnection: False gives the connection up for good instead (its
        #: session is another's now: a reconnection would take it back from that one)
        self.may_reconnect: Callable[[], bool] | None = None
        self.done = threading.Event()  # the loop has forgotten it
        self.io = threading.RLock()  # held by whoever reads or writes the socket: the loop, or a publisher
        self._batching: set[int] = set()  # threads publishing a batch (`batch`): writes wait for its end
        if isinstance(client, ServedClient):
            client.batching = self._batching
        client.on_socket_close = self._socket_closed
        client.on_socket_register_write = self._wants_write
        client.on_socket_unregister_write = self._wrote

    def start(self) -> None:
        """Serve the client, whose `connect()` has returned (its CONNECT is written or queued)."""
        self.loop.call_soon(lambda: self.loop._activate(self))

    def close(self, timeout: float) -> None:
        """Disconnect cleanly (or, while held, drop the connection: see `drop`) and forget the client; wait at
        most `timeout` for it (not on the loop's thread), then drop what is still open."""
        self.loop.call_soon(lambda: self.loop._close(self, clean=True))
        if self.loop.on_thread():
            return
        if not self.done.wait(timeout):
            self.loop.call_soon(lambda: self.loop._close(self, clean=False))

    @property
    def held(self) -> bool:
        """Write nothing on this connection (paho neither, see `ServedClient`)."""
        return self._held

    @held.setter
    def held(self, held: bool) -> None:
        self._held = held
        if isinstance(self.client, ServedClient):
            self.client.held = held

    def hold(self) -> None:
        """(Loop thread) write nothing on this connection until `release`; what arrives is still read."""
        self.held = True

    def release(self) -> None:
        """(Loop thread) write what was queued meanwhile, and go on as usual."""
        self.held = False
        self.loop._settle(self, _OK)

    def drop(self) -> None:
        """(Loop thread) close the connection without writing anything more, and forget the client: the broker
        publishes the will. For a connection that must not be trusted."""
        self.loop._close(self, clean=False)

    @contextlib.contextmanager
    def batch(self) -> Iterator[None]:
        """(Any thread but the loop's) what this thread publishes inside is written at the end, together (see
        `ServedClient._packet_write`): an event and its WoT copy go out in one send. Nothing is written on the
        connection meanwhile (a batch is two publishes long): whoever ends the last batch writes what waits."""
        me = threading.get_ident()
        if me in self._batching or self.loop.on_thread():
            yield
            return
        self._batching.add(me)
        try:
            yield
        finally:
            self._batching.discard(me)
            if self.client.want_write():
                self._wants_write(self.client, None, None)

    # paho's callbacks (any thread)
    def _wants_write(self, client: mqtt.Client, _userdata: Any, _sock: Any) -> None:
        """Something was queued: a publisher writes it at once, as paho does without a network thread, unless
        the loop is reading or writing this connection right now (then the loop writes it), or the publisher
        is in a `batch` (then at the batch's end)."""
        if self._batching and threading.get_ident() in self._batching:
            return
        if not self.loop.on_thread() and self.sock is not None and not self._held and self.io.acquire(False):
            try:
                if self.sock is not None and not self._held:
                    client.loop_write()  # a failure closes the socket: see _socket_closed
                    if client.socket() is not None and not client.want_write():
                        return
            finally:
                self.io.release()
        self.loop.notify(self)

    def _wrote(self, client: mqtt.Client, _userdata: Any, _sock: Any) -> None:
        # paho clears its "registered" flag after checking its queue; a publish from another thread between
        # the two saw the flag still set and did not call `_wants_write`: look again
        if client.want_write():
            self.loop.notify(self)

    def _socket_closed(self, _client: mqtt.Client, _userdata: Any, _sock: Any) -> None:
        """paho closes the socket (right after this): out of the selector first. Off the loop's thread only a
        publisher's write that failed closes it, holding `io`: the loop learns it is lost."""
        self.loop._unregister(self)
        if not self.loop.on_thread():
            self.loop.call_soon(lambda: self.loop._settle(self, _OK))


class _Helpers:
    """At most `size` daemon threads for work that may block, started as work comes and none is idle."""

    def __init__(self, size: int, name: str) -> None:
        self._size = size
        self._name = name
        self._jobs: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._threads = 0
        self._idle = 0

    def submit(self, job: Callable[[], None]) -> None:
        self._jobs.put(job)
        with self._lock:
            if self._idle > 0 or self._threads >= self._size:
                return
            self._threads += 1
            name = f"{self._name}-{self._threads}"
        threading.Thread(target=self._work, name=name, daemon=True).start()

    def _work(self) -> None:
        while True:
            with self._lock:
                self._idle += 1
            job = self._jobs.get()
            with self._lock:
                self._idle -= 1
            try:
                job()
            except Exception:  # noqa: BLE001 - a helper serves every connection: it must live
                log.exception("MQTT helper job failed")


class MqttLoop:
    """The serving thread and its helpers (see the module's doc); `shared()` is the process's one."""

    def __init__(self) -> None:
        self._selector = selectors.DefaultSelector()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        self._calls: deque[Callable[[], None]] = deque()
        self._dirty: deque[Link] = deque()  # links a thread queued something on
        self._signalled = False  # a wake-up byte is on its way: no need for another
        self._links: set[Link] = set()
        self._timers: list[tuple[float, int, Link]] = []  # reconnections due, a heap
        self._trying: dict[tuple[str, int], list[Link]] = {}  # a broker being reconnected to: who waits for it
        self._order = itertools.count()
        self._misc_at = 0.0
        self.helpers = _Helpers(HELPERS, f"{THREAD}-helper")
        self._ident: int | None = None
        self._thread = threading.Thread(target=self._run, name=THREAD, daemon=True)
        self._thread.start()

    # -- any thread ------------------------------------------------------------------------------------

    def on_thread(self) -> bool:
        return threading.get_ident() == self._ident

    def call_soon(self, call: Callable[[], None]) -> None:
        """Run `call` on the loop's thread, in order with the other calls."""
        self._calls.append(call)
        self._wake()

    def notify(self, link: Link) -> None:
        """Something was queued on `link`'s client: write it promptly."""
        self._dirty.append(link)
        self._wake()

    def run_blocking(self, job: Callable[[], None]) -> None:
        """Run `job`, which may block, on a helper thread."""
        self.helpers.submit(job)

    def _wake(self) -> None:
        if self._signalled or self.on_thread():
            return  # the loop looks at its queues before it waits again
        self._signalled = True
        try:
            self._wake_w.send(b"\0")
        except OSError:  # full: it is awake already
            pass

    # -- the loop's thread -----------------------------------------------------------------------------

    def _run(self) -> None:
        self._ident = threading.get_ident()
        while True:
            try:
                self._turn()
            except Exception:  # noqa: BLE001 - it serves every connection: it must live
                log.exception("serving the MQTT connections failed")
                time.sleep(0.1)

    def _turn(self) -> None:
        events = self._selector.select(self._timeout())
        self._signalled = False  # before draining: a wake-up sent from now on is seen next turn
        for key, _mask in events:
            if key.data is None:
                try:
                    self._wake_r.recv(4096)
                except OSError:
                    pass
        while self._calls:
            call = self._calls.popleft()
            try:
                call()
            except Exception:  # noqa: BLE001 - as below
                log.exception("serving the MQTT connections failed")
        for key, mask in events:
            link = key.data
            if link is None or link.sock is not key.fileobj:
                continue  # the wake-up pair, or a socket closed since the wait
            if mask & selectors.EVENT_READ:
                self._guarded(link, self._read)
            if mask & selectors.EVENT_WRITE and link.sock is not None and not link.held:
                self._guarded(link, self._write)
        self._flush()
        now = time.monotonic()
        if now >= self._misc_at:
            self._misc_at = now + MISC
            for link in list(self._links):
                if link.sock is not None and not link.held:
                    self._guarded(link, self._misc)
            self._flush()
        while self._timers and self._timers[0][0] <= now:
            _, _, link = heapq.heappop(self._timers)
            if link.closing:
                self._forget(link)
                continue
            broker = (link.client.host, link.client.port)
            waiting = self._trying.get(broker)
            if waiting is not None:  # one attempt per broker at a time: the others follow its outcome
                waiting.append(link)
                continue
            self._trying[broker] = []
            link.trying = True
            self.run_blocking(functools.partial(self._reconnect, link, broker))

    def _timeout(self) -> float | None:
        if self._calls or self._dirty:
            return 0.0  # queued by this thread itself (a handler that closes a bus): no wake-up was sent
        if not self._links:
            return None
        now = time.monotonic()
        due = self._misc_at
        if self._timers:
            due = min(due, self._timers[0][0])
        return max(0.0, due - now)

    def _flush(self) -> None:
        """Write what other threads (and the callbacks of this turn) queued."""
        for _ in range(len(self._dirty)):
            link = self._dirty.popleft()
            if link.sock is not None and not link.held and link.client.want_write():
                self._guarded(link, self._write)

    def _guarded(self, link: Link, step: Callable[[Link], MQTTErrorCode]) -> None:
        with link.io:
            try:
                rc = step(link)
            except Exception:  # noqa: BLE001 - one connection's fault must not stop the others' service
                log.exception("serving the MQTT connection %s failed", link.name)
                rc = _OK
            self._settle(link, rc)

    @staticmethod
    def _read(link: Link) -> MQTTErrorCode:
        client = link.client
        rc = client.loop_read()
        sock = client.socket()
        for _ in range(READ_PACKETS):  # on while more is there (paho keeps no bytes it has not handled)
            if rc is not _OK or sock is None:
                break
            if not (isinstance(sock, ssl.SSLSocket) and sock.pending() > 0):  # decrypted: the selector would not say
                if not _readable(sock):
                    break
            rc = client.loop_read()
            sock = client.socket()
        return rc

    @staticmethod
    def _write(link: Link) -> MQTTErrorCode:
        return link.client.loop_write()

    @staticmethod
    def _misc(link: Link) -> MQTTErrorCode:
        return link.client.loop_misc()  # a PINGREQ when due; a connection whose broker stays silent dropped

    def _settle(self, link: Link, rc: MQTTErrorCode) -> None:
        """After a step: write what it queued, watch writability while a write would block; a lost connection
        is reconnected later (or forgotten when closing)."""
        with link.io:
            self._settled(link, rc)

    def _settled(self, link: Link, rc: MQTTErrorCode) -> None:
        if link.away or link not in self._links:
            return  # no socket now, or forgotten
        client = link.client
        sock = client.socket()
        if rc is _OK and sock is not None and sock is not link.sock:
            self._unregister(link)  # paho made a new connection itself (it does for some refusals)
            self._register(link, sock)
        if rc is _OK and sock is not None and not link.held and client.want_write():
            rc = client.loop_write()
            sock = client.socket()
        if rc is not _OK or sock is None:
            self._lost(link)
            return
        if link.delay is not None and client.is_connected():
            link.delay = None  # accepted: the next loss waits the shortest delay again
        # not while a thread publishes a batch: nothing is written then, and its end writes (or wakes the loop)
        writing = not link.held and not link._batching and client.want_write()
        if writing != link.writing:
            link.writing = writing
            mask = selectors.EVENT_READ | (selectors.EVENT_WRITE if writing else 0)
            self._selector.modify(sock, mask, link)

    def _register(self, link: Link, sock: Any) -> None:
        link.sock = sock
        link.writing = False
        self._selector.register(sock, selectors.EVENT_READ, link)

    def _unregister(self, link: Link) -> None:
        sock, link.sock = link.sock, None
        link.writing = False
        if sock is not None:
            try:
                self._selector.unregister(sock)
            except (KeyError, ValueError, OSError):
                pass

    def _activate(self, link: Link) -> None:
        self._links.add(link)
        with link.io:
            sock = link.client.socket()
            if sock is None:
                self._lost(link)
                return
            self._register(link, sock)
            self._settle(link, _OK)

    def _lost(self, link: Link) -> None:
        """The connection is gone: reconnect after the back-off, unless the client is closing."""
        if link.away:
            return  # a reconnection is under way already
        self._unregister(link)
        link.held = False
        if link.closing:
            self._forget(link)
            return
        link.delay = link.min_delay if link.delay is None else min(link.delay * 2, link.max_delay)
        link.away = True
        heapq.heappush(self._timers, (time.monotonic() + link.delay, next(self._order), link))

    def _reconnect(self, link: Link, broker: tuple[str, int] | None) -> None:
        """(Helper thread) connect the client again: TCP, TLS and CONNECT; the loop serves it from then on.
        `broker`: this attempt is the one the other clients of that broker wait for (see `_turn`): a broker
        that drops packets costs `connect_timeout` per attempt, and a fleet's hundred attempts in a row
        would keep every robot away for minutes after it is back."""
        if link.may_reconnect is not None and not link.may_reconnect():
            self.call_soon(lambda: self._given_up(link, broker))
            return
        try:
            link.client.reconnect()
        except Exception as exc:  # noqa: BLE001 - refused, unreachable, TLS: tried again after the back-off
            log.debug("reconnecting to the MQTT broker failed: %s", exc)
            self.call_soon(lambda: self._failed(link, broker))
            return
        self.call_soon(lambda: self._back(link, broker))

    def _failed(self, link: Link, broker: tuple[str, int] | None) -> None:
        """The attempt failed: it, and those that waited for it, wait their next back-off."""
        link.trying = False
        for other in [link, *self._trying.pop(broker, [])] if broker is not None else [link]:
            other.away = False
            self._lost(other)

    def _given_up(self, link: Link, broker: tuple[str, int] | None) -> None:
        """`may_reconnect` said no: the client is forgotten (closing); the clients that waited for this broker
        try now, each on its own (nothing was learnt of the broker)."""
        self._go_on(broker)
        link.trying = link.away = False
        link.closing = True
        self._forget(link)

    def _go_on(self, broker: tuple[str, int] | None) -> None:
        """The clients that waited for this broker's attempt try now, each on its own."""
        for other in self._trying.pop(broker, []) if broker is not None else []:
            if other.closing:
                other.away = False
                self._forget(other)
            else:
                other.trying = True
                self.run_blocking(functools.partial(self._reconnect, other, None))

    def _back(self, link: Link, broker: tuple[str, int] | None) -> None:
        """Connected: serve it; the clients that waited for this broker try now, each on its own."""
        self._go_on(broker)
        link.trying = link.away = False
        with link.io:
            sock = link.client.socket()
            if sock is None:
                self._lost(link)
                return
            self._register(link, sock)
            if link.closing:  # closed while it was reconnecting: end this connection at once
                link.client.disconnect()
            self._settle(link, _OK)

    def _close(self, link: Link, *, clean: bool) -> None:
        """Stop serving `link`: a clean DISCONNECT (`clean`, and not held) or a drop without writing anything
        (the broker publishes the will); it is forgotten once its socket is gone."""
        with link.io:
            self._closing(link, clean=clean)

    def _closing(self, link: Link, *, clean: bool) -> None:
        first = not link.closing
        link.closing = True
        if link.sock is None:
            if not link.trying:
                self._forget(link)  # (a reconnection due later finds it closing)
            return  # else the helper's reconnection ends at once
        if clean and not link.held:
            if first:
                link.client.disconnect()  # queued after what was published before
                self._settle(link, _OK)
            return
        link.held = True
        self._unregister(link)
        sock: Any = link.client.socket()
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except (OSError, AttributeError):
            pass
        for _ in range(64):  # paho reads the end of the stream, closes its socket and says so
            if link.client.socket() is None or link.client.loop_read() is not _OK:
                break
        self._forget(link)

    def _forget(self, link: Link) -> None:
        self._unregister(link)
        self._links.discard(link)
        link.done.set()


def _readable(sock: Any) -> bool:
    """Whether `sock` has something to read now (poll: descriptors past select's 1024 too)."""
    if not hasattr(select, "poll"):
        return bool(select.select([sock], [], [], 0)[0])
    poller = select.poll()
    poller.register(sock, select.POLLIN)
    return bool(poller.poll(0))


_shared: MqttLoop | None = None
_shared_lock = threading.Lock()


def shared() -> MqttLoop:
    """The process's serving loop (started on first use)."""
    global _shared
    with _shared_lock:
        if _shared is None:
            _shared = MqttLoop()
        return _shared
