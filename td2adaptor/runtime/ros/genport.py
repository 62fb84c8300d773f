"""A `RobotPort` onto the generated rclpy or rospy component classes: how the edge node reaches real ROS.

The generated packages (issue 3) offer, per component (the names are the contract's, `model/genapi.py`),
`construct_<action>_Msg(**fields)`, `call_<action>(request, *, timeout)` (procedure runs return
`Started(mission_id, response)`, queries and cancels accept `mission_id=`), `get_<property>_value(timeout=)`,
`construct_<property>_Msg` / `publish_<property>_Msg`, and raise `ServiceUnavailable` / `CallTimeout` /
`CallFailed` / `NoMessage`.
This adapter turns dicts into those calls and messages back into dicts, and maps the errors onto
`PortError`s. The engine calls it from several threads at once: on ROS 2 up to `CALLS_PER_COMPONENT` calls
of one component overlap (an rclpy client takes concurrent requests, each with its own future; the engine
keeps one mission per component); on ROS 1 the calls of one component are made one at a time.

Values use the field names of the robot's own ROS version, as the event schemas and the robot's published
TD declare them: a ROS 1 time or duration is `{"secs": ..., "nsecs": ...}`, a ROS 2 one `{"sec": ...,
"nanosec": ...}` (the generated rospy constructors accept either spelling on the way in).
Only the standard library and `td2adaptor.model` (with `genapi`) are imported: the ROS 1 bridge runs this module
under a ROS 1 interpreter.
"""

from __future__ import annotations

import array
import importlib
import inspect
import math
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from td2adaptor.model import Model, ProcedureRole
from td2adaptor.model import genapi as api
from td2adaptor.runtime.ros.port import (
    Answered,
    CancelDone,
    GoalEnd,
    GoalListener,
    NoValue,
    PortCallFailed,
    PortError,
    PortRejected,
    PortTimeout,
    PortUnavailable,
    StalePackage,
    StartResult,
)

#: seconds a goal's end waits for feedback that trails its result (the generated goal record's `feedback_grace`);
#: ROS 1 sends feedback and result over two TCPROS connections read by two threads (and the node reads them
#: through the bridge), so a feedback message can trail its result by much more there. The run setting
#: `goal_feedback_grace` (RuntimeConfig) overrides it: it is also the least a goal's terminal event waits
FEEDBACK_GRACE = {"ros2": 0.01, "ros1": 0.1}
#: ... but for no longer than this in all (the generated record's own bound)
TRAIL_LIMIT = 1.0
#: ROS 2 calls of one component in flight at once (more wait): a service's request and response readers keep the
#: last 10 messages by default (rmw's services QoS), so a flood of concurrent calls to one service loses some
CALLS_PER_COMPONENT = 4
#: per message type: its field names (rosidl's get_fields_and_field_types builds a new dict at every call; a genpy
#: message's slots but its private ones)
_FIELDS: dict[type, tuple[str, ...]] = {}


def to_plain(value: Any) -> Any:
    """A ROS 1 (genpy) or ROS 2 (rosidl) message, or a value inside one, as JSON-compatible data.

    NaN and infinities (a sensor's "no reading") become None: JSON has no such numbers, and one of them must
    not keep a whole message off the bus.

    Every query answer and every goal feedback goes through here on the thread that took it: the exact types
    ROS gives (a plain int, float or str; a message type met before; an array.array of integers) are
    recognised first, by their type alone, and only the rest goes through the general checks (`_general`),
    which were about a tenth of the edge node's CPU per query answered.
    """
    kind = type(value)
    if kind in _SCALARS:
        return value
    if kind is float:
        return value if math.isfinite(value) else None
    names = _FIELDS.get(kind)
    if names is not None:
        return _message(value, names)
    if kind is array.array and value.typecode not in "fd":  # a rosidl sequence of integers: Python ints
        return value.tolist()
    return _general(value)


def _message(value: Any, names: tuple[str, ...]) -> dict[str, Any]:
    """A message of a type whose field names are known, its scalar fields taken as they are."""
    out: dict[str, Any] = {}
    for name in names:
        item = getattr(value, name)
        out[name] = item if type(item) in _SCALARS else to_plain(item)
    return out


def _general(value: Any) -> Any:
    """`to_plain` of what its exact types did not cover: subclasses, mappings, bytes, genpy messages, sequences."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    fields = getattr(value, "get_fields_and_field_types", None)
    if callable(fields):  # rosidl message
        names = _FIELDS[type(value)] = tuple(fields())
        return _message(value, names)
    slots = getattr(type(value), "__slots__", None)
    if isinstance(slots, (list, tuple)) and list(slots) == ["secs", "nsecs"]:  # genpy Time / Duration
        return {"secs": int(value.secs), "nsecs": int(value.nsecs)}
    if isinstance(slots, (list, tuple)) and slots and all(isinstance(s, str) for s in slots):  # genpy message
        names = _FIELDS[type(value)] = tuple(s for s in slots if not s.startswith("_"))
        return _message(value, names)
    if hasattr(value, "tolist"):  # numpy arrays and scalars, array.array (a rosidl sequence of numbers)
        return to_plain(value.tolist())
    if isinstance(value, (list, tuple)) or type(value).__name__ == "array":
        if all(type(v) in _SCALARS for v in value):  # a sequence of integers or texts: as it is, no call each
            return list(value)
        if all(type(v) is float for v in value):  # of floats: only the ones not finite change
            return [v if math.isfinite(v) else None for v in value]
        return [to_plain(v) for v in value]
    return str(value)


#: the types `to_plain` gives back as they are (a float only when finite)
_SCALARS = frozenset({int, str, bool, type(None)})


def _start_result(result: Any) -> StartResult:
    """A run's answer (the generated `Started`: its mission id and response; else the response alone)."""
    if hasattr(result, "mission_id") and hasattr(result, "response"):
        mid = result.mission_id
        return StartResult(to_plain(result.response), int(mid) if mid is not None else None)
    return StartResult(to_plain(result))


def _port_error(exc: BaseException) -> PortError:
    """Map a generated package's error onto the port's error kinds (by class name, across both backends)."""
    names = {cls.__name__ for cls in type(exc).__mro__}
    response = getattr(exc, "response", None)
    plain = to_plain(response) if response is not None else None
    message = str(exc).strip()  # may be empty: the error event then says the kind in words (runtime/engine/words.py)
    if "GoalRejected" in names:  # the server's words, without the action's name in front
        return PortRejected(str(getattr(exc, "message", "") or message))
    if "ServiceUnavailable" in names:
        return PortUnavailable(message)
    if "CallTimeout" in names:
        return PortTimeout(message)
    if "NoMessage" in names:
        return NoValue(message)
    return PortCallFailed(message, response=plain if isinstance(plain, Mapping) else None)


def _unlocked(component: str, fn: Callable[[], Any]) -> Any:
    """`fn()` with its errors as the port's (`GeneratedPort._guarded` without the component's lock)."""
    try:
        return fn()
    except PortError:
        raise
    except Exception as exc:  # noqa: BLE001 - every generated error becomes a port error
        raise _mapped(component, exc) from exc


def _mapped(component: str, exc: Exception) -> PortError:
    """An error of a call into the generated package as the port's."""
    if isinstance(exc, (TypeError, ValueError, KeyError)):  # bad payload for the message constructor
        return PortCallFailed(f"{component}: {exc}")
    return _port_error(exc)


@dataclass(frozen=True)
class Layout:
    """What the port needs to know of a model: its component classes, its procedure run actions and the
    queries and cancels whose requests carry a mission id (`Procedure.slot`: their methods take `mission_id=`)."""

    components: tuple[str, ...]
    runs: frozenset[tuple[str, str]] = frozenset()
    ids: frozenset[tuple[str, str]] = frozenset()
    #: per ROS version ("ros1", "ros2"): the hash of the model a package of that version must record; and the
    #: model's ports (`genapi.ports`), to say what differs when it does not
    hashes: tuple[tuple[str, str], ...] = ()
    ports: Mapping[str, Any] | None = field(default=None, compare=False)

    @classmethod
    def of(cls, model: Model) -> Layout:
        runs = {(c.name, s.name) for c in model.components for s in c.services if s.procedure_role is ProcedureRole.RUN}
        ids = {
            (c.name, action)
            for c in model.components
            for p in c.procedures
            for role, action in (("query", p.query), ("cancel", p.cancel))
            if action is not None and p.slot(role)
        }
        hashes = tuple((d, api.model_hash(model, d)) for d in ("ros1", "ros2"))
        return cls(tuple(c.name for c in model.components), frozenset(runs), frozenset(ids), hashes, api.ports(model))

    def to_json(self) -> dict[str, Any]:
        pairs = {"runs": self.runs, "ids": self.ids}
        out = {"components": list(self.components), **{k: sorted([c, a] for c, a in v) for k, v in pairs.items()}}
        return {**out, "hashes": dict(self.hashes), "ports": self.ports}

    def check(self, module: ModuleType, distro: str) -> None:
        """Refuse (`StalePackage`) a generated package whose record (`genapi.RECORD`) is not of this model."""
        want = dict(self.hashes).get(distro)
        if want is None:  # a layout made by hand (tests): nothing to compare with
            return
        name = str(getattr(module, "__name__", module))
        try:
            record = importlib.import_module(f"{name}.{api.RECORD}")
        except ImportError:
            record = None
        have = getattr(record, "MODEL_HASH", None)
        if have == want:
            return
        if have is None:
            why = "it records no model (generated by an older td2adaptor)"
        else:
            why = "its model differs" + _differences(getattr(record, "PORTS", None), self.ports)
        raise StalePackage(
            f"the adaptor package {name} was not generated from this Thing Description: {why}", name, distro
        )

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Layout:
        def pairs(key: str) -> frozenset[tuple[str, str]]:
            found: Iterable[Any] = data.get(key) or ()
            return frozenset((str(c), str(a)) for c, a in found)

        hashes = tuple(sorted((str(d), str(h)) for d, h in (data.get("hashes") or {}).items()))
        return cls(tuple(str(c) for c in data["components"]), pairs("runs"), pairs("ids"), hashes, data.get("ports"))


def _differences(have: Any, want: Mapping[str, Any] | None) -> str:
    """What a package's ports lack or have beyond the model's (", only in the TD: ...; only in the package:
    ..."), "" when they are the same (the types or the ROS names differ then)."""
    if not isinstance(have, Mapping) or want is None:
        return ""

    def flat(table: Mapping[str, Any]) -> list[str]:
        kinds = [(c, k) for c, k in table.items() if isinstance(k, Mapping)]
        return [f"{c}.{n}" for c, k in kinds for names in k.values() for n in names]

    theirs, ours = flat(have), flat(want)
    parts = []
    if missing := [p for p in ours if p not in theirs]:
        parts.append("only in the TD: " + ", ".join(missing[:5]) + (", ..." if len(missing) > 5 else ""))
    if extra := [p for p in theirs if p not in ours]:
        parts.append("only in the package: " + ", ".join(extra[:5]) + (", ..." if len(extra) > 5 else ""))
    return (" (" + "; ".join(parts) + ")") if parts else " (its ROS names, types or procedures)"


class GoalFollower:
    """One goal started through a generated `start_<action>`: the handle's callbacks, turned into the port's
    (`GoalListener`), its messages into plain data. The generated goal record keeps the feedback (one buffer)
    and tells its callbacks once and in order, in the ROS client library's threads; this converts and passes
    them on, until `close()` (then it tells nothing more).

    The goal's id is known once `start_<action>` returned its handle, but the server may answer before that
    (ROS 1 reports a goal on another thread while the call returns): what is told before the id is known waits
    in `early` and is passed on, in order, by `ready()`; a record's callbacks are never told twice."""

    def __init__(self, listener: GoalListener) -> None:
        self.listener = listener
        self.handle: Any = None
        self.goal_id = ""
        self.closed = False
        self._lock = threading.Lock()
        self._early: list[Callable[[], None]] | None = []  # None once the id is known

    def _tell(self, call: Callable[[], None]) -> None:
        with self._lock:
            if self._early is not None:
                self._early.append(call)
                return
        call()

    def ready(self, handle: Any) -> None:
        """`start_<action>` returned: the id is known; what waited is told now (this thread), the rest as it comes."""
        self.handle, self.goal_id = handle, str(handle.goal_id)
        while True:
            with self._lock:
                early = self._early
                if not early:
                    self._early = None
                    return
                self._early = []  # what comes while these are told waits its turn
            for call in early:
                call()

    def accepted_cb(self) -> None:
        self._tell(lambda: None if self.closed else self.listener.on_accepted(self.goal_id))

    def status_cb(self, status: str) -> None:
        self._tell(lambda: None if self.closed else self.listener.on_status(str(status)))

    def feedback_cb(self, message: Any) -> None:
        plain = to_plain(message)
        self._tell(lambda: None if self.closed else self.listener.on_feedback(plain))

    def done_cb(self, outcome: Any) -> None:
        status = str(getattr(outcome, "status", "") or "lost")
        result = to_plain(getattr(outcome, "result", None))
        error = getattr(outcome, "error", None)
        failure = _port_error(error) if error is not None and status in ("rejected", "lost") else None
        reason = str(getattr(outcome, "reason", "") or "")
        if not reason and status == "lost" and failure is not None:
            reason = str(failure)
        end = GoalEnd(status, result if isinstance(result, Mapping) else None, reason, failure)
        self._tell(lambda: self._done(end))

    def _done(self, end: GoalEnd) -> None:
        if not self.closed:
            self.closed = True
            self.listener.on_done(end)

    def close(self) -> None:
        self.closed = True


class GeneratedPort:
    """Drive one robot through a generated adaptor package (`package` is the imported module or its name).

    `model` is the compiled model (or just its `Layout`). `distro` "ros2" builds components as
    `Cls(node, robot_name, ...)`, "ros1" as `Cls(robot_name, ...)`. `feedback_grace` is each goal's
    goal record's `feedback_grace` (None: `FEEDBACK_GRACE` of the distro), `server_timeout` a ROS 2 goal handle's
    `server_timeout` (how long its action server may stay silent before the goal ends lost; None: the handle's
    default).
    """

    def __init__(
        self,
        model: Model | Layout,
        package: ModuleType | str,
        robot_name: str,
        *,
        distro: str,
        node: Any = None,
        timeout: float = 10.0,
        wait_timeout: float = 5.0,
        feedback_grace: float | None = None,
        server_timeout: float | None = None,
    ) -> None:
        if distro not in ("ros1", "ros2"):
            raise ValueError(f"distro must be 'ros1' or 'ros2', not {distro!r}")
        if distro == "ros2" and node is None:
            raise ValueError("a ROS 2 port needs the rclpy node that owns its clients (node=...)")
        self.layout = model if isinstance(model, Layout) else Layout.of(model)
        self.robot_name = robot_name
        self.node = node  # ROS 2: the rclpy node that owns the clients (presence reads its graph)
        self.distro = distro
        self.feedback_grace = FEEDBACK_GRACE[distro] if feedback_grace is None else feedback_grace
        self.server_timeout = server_timeout
        module = importlib.import_module(package) if isinstance(package, str) else package
        self.layout.check(module, distro)
        self.components: dict[str, Any] = {}
        self._locks: dict[str, threading.BoundedSemaphore] = {}
        self._constructors: dict[tuple[str, str], Callable[..., Any]] = {}  # `_construct`'s, by component and name
        self._goals: dict[tuple[str, str, str], GoalFollower] = {}
        self._goals_lock = threading.Lock()
        for name in self.layout.components:
            cls = getattr(module, name, None)
            if cls is None:
                raise PortCallFailed(
                    f"{getattr(module, '__name__', module)} has no component class {name}: "
                    "was it generated from another Thing Description?"
                )
            args: tuple[Any, ...] = (node, robot_name) if distro == "ros2" else (robot_name,)
            instance = cls(*args, timeout=timeout, wait_timeout=wait_timeout)
            instance.register()
            self.components[name] = instance
            self._locks[name] = threading.BoundedSemaphore(CALLS_PER_COMPONENT if distro == "ros2" else 1)

    def _method(self, component: str, name: str) -> Callable[..., Any]:
        try:
            return getattr(self.components[component], name)  # type: ignore[no-any-return]
        except (KeyError, AttributeError):
            raise PortCallFailed(f"the adaptor has no {component}.{name}") from None

    def _construct(self, component: str, name: str) -> Callable[..., Any]:
        """The generated constructor `name`, called with the message's own field names (`by_field`)."""
        key = (component, name)
        construct = self._constructors.get(key)
        if construct is None:
            construct = self._constructors[key] = by_field(self._method(component, name))
        return construct

    def _guarded(self, component: str, fn: Callable[[], Any]) -> Any:
        try:
            with self._locks[component]:
                return fn()
        except PortError:
            raise
        except Exception as exc:  # noqa: BLE001 - every generated error becomes a port error
            raise _mapped(component, exc) from exc

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> StartResult:
        construct = self._construct(component, api.CONSTRUCT_REQUEST(action))
        call = self._method(component, api.CALL(action))

        return self._guarded(component, lambda: _start_result(call(construct(**payload), timeout=timeout)))  # type: ignore[no-any-return]

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        """Call a query or cancel; the mission id goes where its request carries one (`mission_id=`, see
        `Layout.ids`), else the robot is asked about its current procedure (a request that cannot name it: ROS447)."""
        call = self._method(component, api.CALL(action))
        if (component, action) in self.layout.ids:
            return self._guarded(component, lambda: to_plain(call(**{api.MISSION_ID: mission_id}, timeout=timeout)))  # type: ignore[no-any-return]
        return self._guarded(component, lambda: to_plain(call(timeout=timeout)))  # type: ignore[no-any-return]

    def cancel(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        return self.query(component, action, mission_id, timeout)

    def call(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Mapping[str, Any]:
        construct = self._construct(component, api.CONSTRUCT_REQUEST(action))
        call = self._method(component, api.CALL(action))
        if (component, action) in self.layout.runs:
            return self.start(component, action, payload, timeout).response

        def run() -> Any:
            result = call(construct(**payload), timeout=timeout)
            return to_plain(getattr(result, "response", result))

        return self._guarded(component, run)  # type: ignore[no-any-return]

    # -- calls without a waiting thread (the `QuickCall` protocol: ROS 2 packages with `call_<action>_then`) ---

    def try_start(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, on_done: Answered
    ) -> bool:
        return self._then(component, action, on_done, _start_result, payload, timeout=timeout)

    def try_query(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        if (component, action) in self.layout.ids:
            return self._then(component, action, on_done, to_plain, None, timeout=timeout, mission_id=mission_id)
        return self._then(component, action, on_done, to_plain, None, timeout=timeout)

    def try_cancel(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        return self.try_query(component, action, mission_id, timeout, on_done)

    def try_call(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, on_done: Answered
    ) -> bool:
        if (component, action) in self.layout.runs:
            return self.try_start(component, action, payload, timeout, lambda r, e: on_done(r and r.response, e))
        return self._then(
            component, action, on_done, lambda r: to_plain(getattr(r, "response", r)), payload, timeout=timeout
        )

    def _then(
        self,
        component: str,
        action: str,
        on_done: Answered,
        convert: Callable[[Any], Any],
        payload: Mapping[str, Any] | None,
        **kwargs: Any,
    ) -> bool:
        """Send a call with the generated `call_<action>_then` when one of the component's `CALLS_PER_COMPONENT`
        is free at once; its answer converted to plain data (or its error to a port error) to `on_done`."""
        then = getattr(self.components.get(component), api.CALL_THEN(action), None)
        lock = self._locks.get(component)
        if self.distro != "ros2" or not callable(then) or lock is None or not lock.acquire(blocking=False):
            return False
        told = False

        def done(answer: Any, error: BaseException | None) -> None:
            nonlocal told
            told = True
            lock.release()
            failure: PortError | None = None
            value = None
            try:
                if error is not None:
                    raise error
                value = convert(answer)
            except PortError as exc:
                failure = exc
            except Exception as exc:  # noqa: BLE001 - every generated error becomes a port error
                failure = _mapped(component, exc)
            on_done(value, failure)

        try:
            if payload is not None:
                kwargs["request"] = self._construct(component, api.CONSTRUCT_REQUEST(action))(**payload)
            sent = bool(then(on_done=done, **kwargs))
        except Exception as exc:  # noqa: BLE001 - a payload the request does not take: the call fails at once
            if not told:
                lock.release()
                on_done(None, _mapped(component, exc))
            return True
        if not sent:
            lock.release()
        return sent

    def read_property(self, component: str, name: str, timeout: float) -> Any:
        get = self._method(component, api.GET(name))
        return self._guarded(component, lambda: to_plain(get(timeout=timeout)))

    def watch_property(self, component: str, name: str, callback: Callable[[Any], None]) -> Callable[[], None]:
        """Call `callback` with every message of a subscribed property (the raw ROS message, on the ROS
        side's thread: it must not block); returns what removes it (property_mode message, streams.py)."""
        return self._method(component, api.ON(name))(callback)  # type: ignore[no-any-return]

    def watch_property_serialized(
        self, component: str, name: str, callback: Callable[[bytes], None]
    ) -> Callable[[], None] | None:
        """`watch_property` with each message's serialized bytes as received (a ROS 2 adaptor's
        `on_<name>_serialized`); None when the adaptor has no such method (generated before it existed)."""
        method = getattr(self.components.get(component), api.ON_SERIALIZED(name), None)
        if not callable(method):
            return None
        return method(callback)  # type: ignore[no-any-return]

    def write_property(self, component: str, name: str, value: Any) -> None:
        construct = self._construct(component, api.CONSTRUCT_MESSAGE(name))
        publish = self._method(component, api.PUBLISH(name))
        fields = value if isinstance(value, Mapping) else {"data": value}
        self._guarded(component, lambda: publish(construct(**fields)))

    # -- ROS actions (the `GoalPort` protocol) --------------------------------------------------------------

    def start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str:
        return self._start_goal(
            component, action, payload, timeout, listener, lambda run: self._guarded(component, run)
        )

    def try_start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str | None:
        """`start_goal` on ROS 2 when one of the component's `CALLS_PER_COMPONENT` is free at once (the generated
        `start_X` itself returns at once); None otherwise, nothing sent (`QuickGoalStart`)."""
        lock = self._locks.get(component)
        if self.distro != "ros2" or lock is None or not lock.acquire(blocking=False):
            return None
        try:
            return self._start_goal(
                component, action, payload, timeout, listener, lambda run: _unlocked(component, run)
            )
        finally:
            lock.release()

    def _start_goal(
        self,
        component: str,
        action: str,
        payload: Mapping[str, Any],
        timeout: float,
        listener: GoalListener,
        guarded: Callable[[Callable[[], Any]], Any],
    ) -> str:
        construct = self._construct(component, api.CONSTRUCT_GOAL(action))
        start = self._method(component, api.START(action))
        follower = GoalFollower(listener)

        def run() -> Any:
            return start(
                construct(**payload),
                on_accepted=follower.accepted_cb,
                on_status=follower.status_cb,
                on_feedback=follower.feedback_cb,
                on_done=follower.done_cb,
                timeout=timeout,
                feedback_grace=self.feedback_grace,
            )

        return self._follow(component, action, follower, guarded(run))

    def _follow(self, component: str, action: str, follower: GoalFollower, handle: Any) -> str:
        """Follow the goal of the generated package's `handle` (started or rejoined) through `follower`: the goal
        id, the follower kept until the goal ends."""
        if self.server_timeout is not None and hasattr(handle, "server_timeout"):
            handle.server_timeout = self.server_timeout  # before the ticker's first look: that is after an answer
        follower.ready(handle)
        with self._goals_lock:
            if not follower.closed:  # ended already (refused at once): nothing to keep
                self._goals[(component, action, follower.goal_id)] = follower
        return follower.goal_id

    def rejoin_goal(self, component: str, action: str, goal: str, timeout: float, listener: GoalListener) -> None:
        """Follow a goal the server accepted from another client by its id (`GoalRejoin`), through the generated
        `rejoin_<action>`: told to `listener` as a goal this port started."""
        rejoin = self._method(component, api.REJOIN(action))
        follower = GoalFollower(listener)

        def run() -> Any:
            return rejoin(
                goal,
                on_accepted=follower.accepted_cb,
                on_status=follower.status_cb,
                on_feedback=follower.feedback_cb,
                on_done=follower.done_cb,
                timeout=timeout,
                feedback_grace=self.feedback_grace,
            )

        self._follow(component, action, follower, self._guarded(component, run))

    def _follower(self, component: str, action: str, goal: str) -> GoalFollower | None:
        with self._goals_lock:
            return self._goals.get((component, action, goal))

    def request_cancel(self, component: str, action: str, goal: str, timeout: float, on_done: CancelDone) -> None:
        follower = self._follower(component, action, goal)
        if follower is None:
            failure = PortCallFailed(f"{component}.{action}: no goal {goal} is followed here")
            on_done(False, failure)
            return

        def answered(outcome: Any) -> None:
            error = getattr(outcome, "error", None)
            on_done(bool(getattr(outcome, "canceling", False)), _port_error(error) if error is not None else None)

        try:
            follower.handle.request_cancel(answered, timeout=timeout)
        except Exception as exc:  # noqa: BLE001 - every generated error becomes a port error
            on_done(False, _port_error(exc))

    def forget_goal(self, component: str, action: str, goal: str) -> None:
        with self._goals_lock:
            follower = self._goals.pop((component, action, goal), None)
        if follower is not None:
            follower.close()

    def close(self) -> None:
        with self._goals_lock:
            followers, self._goals = list(self._goals.values()), {}
        for follower in followers:
            follower.close()
        for instance in self.components.values():
            close = getattr(instance, "close", None)
            if callable(close):
                close()


def by_field(construct: Callable[..., Any]) -> Callable[..., Any]:
    """`construct` (a generated `construct_*` method) taking the message's own field names: the generator gives
    a field named like a Python keyword or builtin, or like a parameter of its methods, a trailing `_`
    (`open_`, `goal_`: backends/_python/names.py), and the events carry the ROS names (`open`, `goal`). Before,
    such an invoke failed with "construct_setDoor_Msg() got an unexpected keyword argument 'open'"."""
    try:
        params = inspect.signature(construct).parameters
    except (TypeError, ValueError):  # no signature to read: called as it is
        return construct
    renamed = {p[:-1]: p for p in params if p.endswith("_") and len(p) > 1 and p[:-1] not in params}
    if not renamed:
        return construct

    def by_name(**fields: Any) -> Any:
        return construct(**{renamed.get(name, name): value for name, value in fields.items()})

    return by_name
