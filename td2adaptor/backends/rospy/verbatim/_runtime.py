"""Runtime support of the generated component classes: bounded service calls, latest-message subscribers,
publishers, and building messages from mappings. Generated with the package; needs only rospy and genpy.

rospy service calls have no timeout of their own. A call here is bounded like this: the first call on a
connection waits for the service with `rospy.wait_for_service` (bounded) and then runs in a worker thread
joined with the remaining time; later calls reuse that persistent connection from the caller's thread with
a socket deadline, which is about 14 times faster than a new connection per call. A connection that failed
or timed out is dropped and made anew on the next call.
"""

from __future__ import annotations

import http.client
import importlib
import io
import select
import socket
import struct
import threading
import time
import xmlrpc.client
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Generic, TypeVar, cast

import genpy
import rosgraph
import rospy
import rospy.core
from rospy.exceptions import TransportException, TransportInitError

if TYPE_CHECKING:
    from typing import TypeGuard  # Python 3.10; only in annotations here, which Python 3.8 never evaluates

from .common import Callbacks, check_float32, check_float64, check_message
from .errors import CallFailed, CallTimeout, InvalidMessage, NoMessage, NotInitialized, ServiceUnavailable

Req = TypeVar("Req")
Resp = TypeVar("Resp")
M = TypeVar("M")


def require_node() -> None:
    """rospy allows one node per process and it is the caller's: check that it exists."""
    if not rospy.core.is_initialized():
        raise NotInitialized("call rospy.init_node(...) once in this process before using the adaptor")


class TimedTransport(xmlrpc.client.Transport):
    """An XML-RPC transport whose connections time out (xmlrpc.client's default waits forever)."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


#: seconds a look at the ROS master (`master_state`) may take
MASTER_TIMEOUT = 2.0


@dataclass(frozen=True)
class MasterState:
    """What the ROS master knows at one moment: the services that have a provider, the topics that have a
    publisher (resolved names)."""

    services: frozenset[str]
    publishers: frozenset[str]


def master_state(timeout: float = MASTER_TIMEOUT) -> MasterState:
    """The master's system state (one `getSystemState` call, at most `timeout` seconds); nothing is there when
    the master cannot be reached: then no server can be either."""
    try:
        proxy = xmlrpc.client.ServerProxy(rosgraph.get_master_uri(), transport=TimedTransport(timeout))
        reply: Any = proxy.getSystemState(rospy.get_name())
        code, _, (publishers, _, services) = reply
    except (OSError, xmlrpc.client.Error, TypeError, ValueError):
        return MasterState(frozenset(), frozenset())
    if code != 1:
        return MasterState(frozenset(), frozenset())
    return MasterState(
        frozenset(str(name) for name, nodes in services if nodes),
        frozenset(str(name) for name, nodes in publishers if nodes),
    )


# ---------------------------------------------------------------------------------------------------------
# building messages


def to_msg(cls: type[M], value: M | Mapping[str, Any] | None) -> M:
    """`value` as a `cls` message: the message itself, one built from a mapping of its fields, or a default."""
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    return _from_mapping(cls, _mapping(value, f"{_type_name(cls)} or a mapping of its fields"))


def to_msgs(cls: type[M], values: Sequence[M | Mapping[str, Any]] | None) -> list[M]:
    """A list of `cls` messages from a sequence of messages or mappings."""
    if values is None:
        return []
    return [to_msg(cls, value) for value in _sequence(values, f"a sequence of {_type_name(cls)}")]


def to_time(value: genpy.Time | Mapping[str, int] | None) -> genpy.Time:
    """A ROS 1 time from a genpy.Time or a mapping with secs/nsecs (or ROS 2's sec/nanosec)."""
    return _stamp(genpy.Time, value)


def to_duration(value: genpy.Duration | Mapping[str, int] | None) -> genpy.Duration:
    """A ROS 1 duration from a genpy.Duration or a mapping with secs/nsecs (or ROS 2's sec/nanosec)."""
    return _stamp(genpy.Duration, value)


def to_list(values: Sequence[Any] | None, length: int = 0, default: Any = 0) -> list[Any]:
    """A primitive array field: a list copy, `length` defaults when None (fixed arrays) or empty."""
    if values is None:
        return [default] * length
    return list(_sequence(values, "a sequence"))


def _sequence(value: object, expected: str) -> Sequence[Any]:
    """`value` if it is a sequence of items, else InvalidMessage (callers may pass anything at run time)."""
    if not _is_sequence(value):
        raise InvalidMessage(f"expected {expected}, not {type(value).__name__}")
    return value


def _is_sequence(value: object) -> TypeGuard[Sequence[Any]]:
    """Whether `value` is a sequence of items: not text, bytes or a mapping."""
    return isinstance(value, Sequence) and not isinstance(value, (str, bytes, Mapping))


def _mapping(value: object, expected: str) -> Mapping[Any, Any]:
    """`value` if it is a mapping, else InvalidMessage."""
    if not _is_mapping(value):
        raise InvalidMessage(f"expected {expected}, not {type(value).__name__}")
    return value


def _is_mapping(value: object) -> TypeGuard[Mapping[Any, Any]]:
    return isinstance(value, Mapping)


_S = TypeVar("_S", genpy.Time, genpy.Duration)


def _stamp(cls: type[_S], value: _S | Mapping[str, int] | None) -> _S:
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    fields = _mapping(value, f"{cls.__name__} or a mapping with secs/nsecs")
    unknown = set(fields) - {"secs", "nsecs", "sec", "nanosec"}
    if unknown:
        raise InvalidMessage(f"unknown {cls.__name__.lower()} fields {sorted(unknown)}")
    return cls(int(fields.get("secs", fields.get("sec", 0))), int(fields.get("nsecs", fields.get("nanosec", 0))))


def _type_name(cls: type[Any]) -> str:
    return str(getattr(cls, "_type", cls.__name__))


def _from_mapping(cls: type[M], fields: Mapping[Any, Any]) -> M:
    slots: dict[str, str] = dict(zip(getattr(cls, "__slots__", ()), getattr(cls, "_slot_types", ())))
    values: dict[str, Any] = {}
    for key, value in fields.items():
        slot_type = slots.get(key) if isinstance(key, str) else None
        if slot_type is None:
            raise InvalidMessage(f"{_type_name(cls)} has no field {key!r}")
        values[key] = _convert(slot_type, value, f"{_type_name(cls)}.{key}")
    return cls(**values)


def _convert(slot_type: str, value: Any, field: str) -> Any:
    base, bracket, _ = slot_type.partition("[")
    if bracket:
        if base in ("uint8", "char") or value is None:
            return value if value is not None else b""
        if "/" in base or base == "Header":
            return to_msgs(_message_class(base), value)
        return [_convert(base, item, field) for item in to_list(value)]
    if base == "float64":
        return check_float64(value, field)
    if base == "float32":
        return check_float32(value, field)
    if base == "time":
        return to_time(value)
    if base == "duration":
        return to_duration(value)
    if "/" in base or base == "Header":
        return to_msg(_message_class(base), value)
    return value


@lru_cache(maxsize=None)
def _message_class(ros_type: str) -> type[Any]:
    package, _, name = ros_type.rpartition("/")
    module = importlib.import_module(f"{package or 'std_msgs'}.msg")
    return cast("type[Any]", getattr(module, name))


# ---------------------------------------------------------------------------------------------------------
# service clients


class _DeadlineSocket:
    """Wraps the socket of a persistent connection so that a call's reads and writes end at its deadline.

    The kernel enforces it (SO_RCVTIMEO/SO_SNDTIMEO, set only when the timeout changes), so a call costs no
    extra system call; a reply that needs a second read only gets what is left of the deadline. rospy's
    own switch to blocking mode is ignored; everything else is passed through to the real socket.
    """

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock
        self.deadline: float | None = None
        self.expired = False
        self._armed = 0.0
        self._reads = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sock, name)

    def setblocking(self, flag: bool) -> None:
        """Ignored: the socket stays blocking, bounded by the kernel timeouts."""

    def start(self, deadline: float, timeout: float) -> None:
        """A call begins: it must be over by `deadline` (`timeout` seconds from now)."""
        self.deadline, self.expired, self._reads = deadline, False, 0
        if timeout != self._armed:
            self._set(timeout)
            self._armed = timeout

    def _set(self, seconds: float) -> None:
        seconds = max(seconds, 1e-6)  # zero would mean "wait forever"
        value = struct.pack("ll", int(seconds), int((seconds - int(seconds)) * 1e6))
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, value)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, value)

    def _expire(self) -> socket.timeout:
        self.expired = True
        return socket.timeout("deadline passed")

    def recv(self, size: int) -> bytes:
        if self.deadline is None:
            return self._sock.recv(size)
        while True:
            if self._reads:
                remaining = self.deadline - time.monotonic()
                if remaining <= 0.0:
                    raise self._expire()
                self._set(remaining)
                self._armed = -1.0  # set again at the next call
            self._reads += 1
            try:
                return self._sock.recv(size)
            except BlockingIOError:  # the kernel timeout expired
                if time.monotonic() >= self.deadline:
                    raise self._expire() from None

    def sendall(self, data: bytes) -> None:
        try:
            self._sock.sendall(data)
        except BlockingIOError:
            raise self._expire() from None

    def stale(self) -> bool:
        """An idle connection that is readable was closed by the robot (or is out of step): do not reuse it."""
        try:
            readable, _, _ = select.select([self._sock], [], [], 0.0)
        except (OSError, ValueError):
            return True
        return bool(readable)


class ServiceClient(Generic[Req, Resp]):
    """One service of the robot, called with a bound on the time it may take (see the module docstring)."""

    def __init__(
        self, name: str, service_class: type[Any], request_class: type[Req], response_class: type[Resp]
    ) -> None:
        self.name = name
        self._service_class = service_class
        self._request_class = request_class
        self._response_class = response_class
        self._lock = threading.Lock()
        self._proxy: Any = None
        self._socket: _DeadlineSocket | None = None

    def ready(self, state: MasterState) -> bool:
        """Whether the service has a provider in `state` (what the ROS master knew a moment ago)."""
        return rospy.resolve_name(self.name) in state.services

    def register(self) -> None:
        """Create the service proxy (no connection is made until the first call)."""
        if self._proxy is None:
            with self._lock:
                if self._proxy is None:
                    self._proxy = rospy.ServiceProxy(self.name, self._service_class, persistent=True)

    def close(self) -> None:
        """Close the persistent connection, if any."""
        with self._lock:
            self._drop()

    def call(self, request: Req, timeout: float, wait_timeout: float) -> Resp:
        """Send `request` and return the response, or raise ServiceUnavailable, CallTimeout or CallFailed."""
        if not isinstance(request, self._request_class):
            expected = _type_name(self._request_class)
            raise InvalidMessage(f"{self.name}: expected {expected}, not {type(request).__name__}")
        deadline = time.monotonic() + timeout
        if not self._lock.acquire(timeout=timeout):
            raise CallTimeout(self.name, timeout)
        try:
            sock = self._socket
            if sock is not None and sock.stale():
                self._drop()
                sock = None
            if sock is None:
                return self._connect_and_call(request, deadline, timeout, wait_timeout)
            sock.start(deadline, timeout)
            try:
                return cast(Resp, self._proxy.call(request))
            except Exception as exc:
                if sock.expired:
                    self._drop()
                    raise CallTimeout(self.name, timeout) from None
                raise self._failure(exc) from exc
            finally:
                sock.deadline = None
        finally:
            self._lock.release()

    def _connect_and_call(self, request: Req, deadline: float, timeout: float, wait_timeout: float) -> Resp:
        wait = min(wait_timeout, deadline - time.monotonic())
        if wait <= 0.0:
            raise CallTimeout(self.name, timeout)
        try:
            rospy.wait_for_service(self.name, timeout=wait)
        except rospy.ROSInterruptException:
            raise ServiceUnavailable(self.name, "rospy is shutting down") from None
        except rospy.ROSException:
            raise ServiceUnavailable(self.name, f"waited {wait:.3g} s") from None
        proxy = self._proxy
        if proxy is None:
            proxy = rospy.ServiceProxy(self.name, self._service_class, persistent=True)
        outcome: list[tuple[bool, Any]] = []

        def first_call() -> None:
            try:
                outcome.append((True, proxy.call(request)))
            except BaseException as exc:  # handed to the caller's thread
                outcome.append((False, exc))

        worker = threading.Thread(target=first_call, name=f"td2adaptor call {self.name}", daemon=True)
        worker.start()
        worker.join(max(deadline - time.monotonic(), 0.0))
        if worker.is_alive() or not outcome:
            self._proxy = proxy
            self._drop()  # closing the connection lets the worker's read end
            raise CallTimeout(self.name, timeout)
        ok, value = outcome[0]
        if not ok:
            self._proxy = proxy
            self._drop()
            raise self._failure(value) from value
        transport = getattr(proxy, "transport", None)
        if transport is not None and transport.socket is not None:
            self._socket = _DeadlineSocket(transport.socket)
            transport.socket = self._socket
            self._proxy = proxy
        return cast(Resp, value)

    def _drop(self) -> None:
        proxy, self._proxy, self._socket = self._proxy, None, None
        if proxy is not None:
            try:
                proxy.close()
            except Exception:  # already broken: nothing left to release
                pass

    def _failure(self, exc: BaseException) -> Exception:
        """The adaptor error for what rospy raised."""
        causes = _causes(exc)
        if isinstance(exc, rospy.ROSInterruptException):
            return ServiceUnavailable(self.name, "rospy is shutting down")
        if isinstance(exc, rospy.ROSSerializationException):
            return InvalidMessage(f"{self.name}: {exc}")
        if any(isinstance(c, TransportInitError) for c in causes):
            self._drop()
            return ServiceUnavailable(self.name, f"could not connect: {exc}")
        if isinstance(exc, rospy.ServiceException):
            if any(isinstance(c, TransportException) for c in causes[1:]):
                self._drop()
                return CallFailed(self.name, f"connection lost during the call: {exc}")
            return CallFailed(self.name, str(exc))
        if isinstance(exc, (TransportException, OSError)):
            self._drop()
            return ServiceUnavailable(self.name, f"connection lost: {exc}")
        if isinstance(exc, Exception):
            return exc
        return RuntimeError(f"{self.name}: {exc!r}")


def _causes(exc: BaseException) -> list[BaseException]:
    """`exc` and the exceptions it was raised while handling, outermost first."""
    chain: list[BaseException] = []
    current: BaseException | None = exc
    while current is not None and current not in chain:
        chain.append(current)
        current = current.__cause__ or current.__context__
    return chain


# ---------------------------------------------------------------------------------------------------------
# topics


class TopicSubscriber(Generic[M]):
    """Keeps the latest message of a topic; waits a bounded time for the first one; calls callbacks."""

    def __init__(self, name: str, msg_class: type[M], queue_size: int) -> None:
        self.name = name
        self._msg_class = msg_class
        self._queue_size = queue_size
        self._cond = threading.Condition()
        self._latest: M | None = None
        self._callbacks: Callbacks[M] = Callbacks()
        self._subscriber: Any = None

    def register(self) -> None:
        """Subscribe (once)."""
        if self._subscriber is None:
            require_node()
            with self._cond:
                if self._subscriber is None:
                    self._subscriber = rospy.Subscriber(
                        self.name, self._msg_class, self._receive, queue_size=self._queue_size
                    )

    def close(self) -> None:
        with self._cond:
            subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            subscriber.unregister()

    def _receive(self, msg: M) -> None:
        with self._cond:
            self._latest = msg
            self._cond.notify_all()
        for callback in self._callbacks.current():
            try:
                callback(msg)
            except Exception as exc:  # one failing callback must not starve the others
                rospy.logerr(f"{self.name}: callback {callback!r} failed: {exc!r}")

    def latest(self, timeout: float) -> M:
        """The latest message, waiting at most `timeout` seconds for the first one."""
        self.register()
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._latest is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    raise NoMessage(self.name, timeout)
                self._cond.wait(remaining)
            return self._latest

    def add_callback(self, callback: Callable[[M], None]) -> Callable[[], None]:
        """Call `callback` with every message from now on; returns a function that removes it."""
        self.register()
        return self._callbacks.add(callback)

    def add_serialized_callback(self, callback: Callable[[bytes], None]) -> Callable[[], None]:
        """Call `callback` with every message serialized (ROS 1 wire format); returns what removes it."""

        def serialized(msg: M) -> None:
            buffer = io.BytesIO()
            cast(Any, msg).serialize(buffer)  # genpy messages: unannotated
            callback(buffer.getvalue())

        return self.add_callback(serialized)


class TopicPublisher(Generic[M]):
    """A publisher created once, with the latching and queue size the Thing Description asks for."""

    def __init__(self, name: str, msg_class: type[M], queue_size: int, latch: bool) -> None:
        self.name = name
        self._msg_class = msg_class
        self._queue_size = queue_size
        self._latch = latch
        self._lock = threading.Lock()
        self._publisher: Any = None

    def register(self) -> None:
        """Advertise the topic (once)."""
        if self._publisher is None:
            require_node()
            with self._lock:
                if self._publisher is None:
                    self._publisher = rospy.Publisher(
                        self.name, self._msg_class, queue_size=self._queue_size, latch=self._latch
                    )

    def close(self) -> None:
        with self._lock:
            publisher, self._publisher = self._publisher, None
        if publisher is not None:
            publisher.unregister()

    def publish(self, msg: M) -> None:
        if not isinstance(msg, self._msg_class):
            raise InvalidMessage(f"{self.name}: expected {_type_name(self._msg_class)}, not {type(msg).__name__}")
        check_message(msg, type(msg).__name__, _message_fields)  # a ValueError sends nothing
        self.register()
        self._publisher.publish(msg)


def _message_fields(msg: object) -> Any:
    """A genpy message's (field, type) pairs (a time's and a duration's too), None for any other value."""
    if isinstance(msg, genpy.Time):
        return _TIME_FIELDS
    if isinstance(msg, genpy.Duration):
        return _DURATION_FIELDS
    types = getattr(msg, "_slot_types", None)
    return None if types is None else zip(msg.__slots__, types)  # type: ignore[attr-defined]


#: what ROS 1 serialises a time and a duration as (genpy checks neither when a field is set)
_TIME_FIELDS = (("secs", "uint32"), ("nsecs", "uint32"))
_DURATION_FIELDS = (("secs", "int32"), ("nsecs", "int32"))
