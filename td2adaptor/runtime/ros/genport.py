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

import importlib
import itertools
import math
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from td2adaptor.model import Model, ProcedureRole
from td2adaptor.model import genapi as api
from td2adaptor.runtime.ros.port import (
    GoalProgress,
    NoValue,
    PortCallFailed,
    PortError,
    PortRejected,
    PortTimeout,
    PortUnavailable,
    StalePackage,
    StartResult,
)
from td2adaptor.runtime.workers import Workers

#: how long a goal's feedback pump waits in one go (it re-checks whether it was told to stop in between)
PUMP_WAIT = 1.0
#: after a goal's result, feedback still arriving is kept until none came for this long (see GoalTrack);
#: ROS 1 sends feedback and result over two TCPROS connections read by two threads (and the node reads them
#: through the bridge), so a feedback message can trail its result by much more there. The run setting
#: `goal_feedback_grace` (RuntimeConfig) overrides it: it is also the least a goal's terminal event waits
FEEDBACK_GRACE = {"ros2": 0.01, "ros1": 0.1}
#: ... but for no longer than this in all
TRAIL_LIMIT = 1.0
#: how long reading a goal's buffered feedback waits for a message not there yet: it does not (the least
#: timeout the generated iterators accept); later messages come through the feedback callback
JOIN_WAIT = 1e-6
#: ROS 2 calls of one component in flight at once (more wait): a service's request and response readers keep the
#: last 10 messages by default (rmw's services QoS), so a flood of concurrent calls to one service loses some
CALLS_PER_COMPONENT = 4
#: the threads that follow goals to their end (one per goal in flight; kept for the next goal)
FOLLOWERS = Workers("goal-follower")
#: feedback messages a goal keeps for a caller that has not read them yet (older ones are dropped)
FEEDBACK_KEEP = 1000
#: goal states a goal with feedback is past
_BEFORE_EXECUTING = frozenset({"unknown", "pending", "accepted"})


#: per message type: its field names (rosidl's get_fields_and_field_types builds a new dict at every call)
_FIELDS: dict[type, tuple[str, ...]] = {}


def to_plain(value: Any) -> Any:
    """A ROS 1 (genpy) or ROS 2 (rosidl) message, or a value inside one, as JSON-compatible data.

    NaN and infinities (a sensor's "no reading") become None: JSON has no such numbers, and one of them must
    not keep a whole message off the bus.
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if isinstance(value, Mapping):
        return {str(k): to_plain(v) for k, v in value.items()}
    names = _FIELDS.get(type(value))
    if names is not None:
        return {name: to_plain(getattr(value, name)) for name in names}
    fields = getattr(value, "get_fields_and_field_types", None)
    if callable(fields):  # rosidl message
        names = _FIELDS[type(value)] = tuple(fields())
        return {name: to_plain(getattr(value, name)) for name in names}
    slots = getattr(type(value), "__slots__", None)
    if isinstance(slots, (list, tuple)) and list(slots) == ["secs", "nsecs"]:  # genpy Time / Duration
        return {"secs": int(value.secs), "nsecs": int(value.nsecs)}
    if isinstance(slots, (list, tuple)) and slots and all(isinstance(s, str) for s in slots):
        return {s: to_plain(getattr(value, s)) for s in slots if not s.startswith("_")}  # genpy message
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return to_plain(value.tolist())
    if isinstance(value, (list, tuple)) or type(value).__name__ == "array":
        return [to_plain(v) for v in value]
    return str(value)


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


class GoalTrack:
    """One goal followed through a generated `GoalHandle`: its feedback as dicts, its status and its end.

    Feedback comes from the handle's `on_feedback` callback, registered at once; what arrived before (the
    handle buffers it) is read at once, in the constructor, with its `feedback()` iterator (without waiting
    for more), and every message is taken once: one the callback also sees (the same object) is not added
    again, whichever of the two saw it first. A thread waits for the result; when it came, feedback
    may still trail it (a different channel, and rclpy hands a result over before feedback taken in the same
    wake-up): the goal counts as done once no message came for `grace` (at most `TRAIL_LIMIT`); a message
    later than that is not reported (never after the terminal event). `server_timeout` (None: the handle's
    default) is how long a ROS 2 handle lets the action server stay silent before it takes it as gone (ROS 1
    tells at once): the goal then ends `lost`.
    """

    def __init__(self, handle: Any, grace: float = FEEDBACK_GRACE["ros2"], server_timeout: float | None = None) -> None:
        self.handle = handle
        self.grace = grace
        self.goal_id = str(handle.goal_id)
        if server_timeout is not None and hasattr(handle, "server_timeout"):
            handle.server_timeout = server_timeout
        self._cond = threading.Condition()
        self._items: list[Any] = []
        self._dropped = 0
        self._late: list[Any] = []  # messages the callback took before the buffered ones were read
        self._buffered: list[Any] = []  # buffered messages added whose callback may still come
        self._joined = False
        self._done = False
        self._status = "accepted"
        self._result: Any = None
        self._message = ""
        self._closed = False
        self._remove = handle.on_feedback(self._on_feedback)
        self._join()  # here, not in the thread: feedback arriving from now on is relayed without a hand-off
        FOLLOWERS.submit(self._follow)

    def _add(self, message: Any) -> None:
        """Append one message (lock held)."""
        self._items.append(to_plain(message))
        if len(self._items) > FEEDBACK_KEEP:
            del self._items[0]
            self._dropped += 1
        self._cond.notify_all()

    def _on_feedback(self, message: Any) -> None:
        with self._cond:
            if not self._joined:
                self._late.append(message)
                return
            for i, buffered in enumerate(self._buffered):
                if buffered is message:  # read from the buffer before its callback came: already added
                    del self._buffered[: i + 1]
                    return
            self._buffered = []  # callbacks come in order: the buffered messages are all behind us
            self._add(message)

    def _join(self) -> None:
        """The buffered messages the callback did not see, then the ones it did, in order. The buffer is read
        without waiting for more: a message it holds whose callback has not run yet (the handle buffers it
        first) is added now and skipped when its callback comes."""
        earlier: list[Any] = []
        buffered = getattr(self.handle, "feedback_received", None)  # read no further: no wait at the end
        messages = self.handle.feedback(timeout=JOIN_WAIT)
        try:
            for message in messages if buffered is None else itertools.islice(messages, buffered):
                with self._cond:
                    seen = any(message is m for m in self._late)
                if seen:
                    break
                earlier.append(message)
        except Exception:  # noqa: BLE001 - CallTimeout: the buffer is read; ServiceUnavailable: the end tells
            pass
        with self._cond:
            for message in earlier:
                self._add(message)
            for message in self._late:
                if any(message is m for m in earlier):
                    continue  # the buffer had it too
                self._add(message)
            self._buffered = [m for m in earlier if not any(m is late for late in self._late)]
            self._late = []
            self._joined = True

    def _follow(self) -> None:
        lost = ""
        result: Any = None
        while not self._closed:
            try:
                result = to_plain(self.handle.result(timeout=PUMP_WAIT))
                break
            except Exception as exc:  # noqa: BLE001 - the goal's end, or still running, or its server gone
                names = {c.__name__ for c in type(exc).__mro__}
                if "CallTimeout" in names and not self.handle.done:
                    continue
                response = getattr(exc, "response", None)
                result = to_plain(response) if response is not None else None
                if not self.handle.done:  # the action server went away (ServiceUnavailable's reason says so)
                    lost = str(getattr(exc, "reason", "") or exc) or "the goal's action server did not answer"
                break
        if self._closed:
            return
        deadline = time.monotonic() + TRAIL_LIMIT
        with self._cond:
            count = -1
            while count != len(self._items) + self._dropped and time.monotonic() < deadline:
                count = len(self._items) + self._dropped
                self._cond.wait(self.grace)
            ended = bool(self.handle.done)
            self._status = str(self.handle.status) if ended else "lost"
            self._message = str(getattr(self.handle, "reason", "") or "") if ended else lost
            self._result = result if isinstance(result, Mapping) else None
            self._done = True
            self._cond.notify_all()

    def progress(self, since: int | None, wait: float) -> GoalProgress:
        with self._cond:
            if since is not None:
                self._cond.wait_for(lambda: self._done or self._dropped + len(self._items) > since, wait)
            received = self._dropped + len(self._items)
            new: tuple[Any, ...] = ()
            if since is not None:
                new = tuple(self._items[max(0, since - self._dropped) :])
            status = self._status if self._done else str(self.handle.status)
            if received and status in _BEFORE_EXECUTING:
                # a server sends feedback only while it executes the goal; the status message saying so comes
                # on another topic and can be taken after that feedback
                status = "executing"
            return GoalProgress(new, received, status, self._done, self._result, self._message)

    def close(self) -> None:
        self._closed = True
        try:
            self._remove()
        except Exception:  # noqa: BLE001 - the handle is going away anyway
            pass


class GeneratedPort:
    """Drive one robot through a generated adaptor package (`package` is the imported module or its name).

    `model` is the compiled model (or just its `Layout`). `distro` "ros2" builds components as
    `Cls(node, robot_name, ...)`, "ros1" as `Cls(robot_name, ...)`. `feedback_grace` is each goal's
    `GoalTrack.grace` (None: `FEEDBACK_GRACE` of the distro), `server_timeout` its `GoalTrack.server_timeout`.
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
        self.distro = distro
        self.feedback_grace = FEEDBACK_GRACE[distro] if feedback_grace is None else feedback_grace
        self.server_timeout = server_timeout
        module = importlib.import_module(package) if isinstance(package, str) else package
        self.layout.check(module, distro)
        self.components: dict[str, Any] = {}
        self._locks: dict[str, threading.BoundedSemaphore] = {}
        self._goals: dict[tuple[str, str, str], GoalTrack] = {}
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

    def _guarded(self, component: str, fn: Callable[[], Any]) -> Any:
        try:
            with self._locks[component]:
                return fn()
        except PortError:
            raise
        except (TypeError, ValueError, KeyError) as exc:  # bad payload for the message constructor
            raise PortCallFailed(f"{component}: {exc}") from exc
        except Exception as exc:  # noqa: BLE001 - every generated error becomes a port error
            raise _port_error(exc) from exc

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> StartResult:
        construct = self._method(component, api.CONSTRUCT_REQUEST(action))
        call = self._method(component, api.CALL(action))

        def run() -> StartResult:
            result = call(construct(**payload), timeout=timeout)
            if hasattr(result, "mission_id") and hasattr(result, "response"):
                mid = result.mission_id
                return StartResult(to_plain(result.response), int(mid) if mid is not None else None)
            return StartResult(to_plain(result))

        return self._guarded(component, run)  # type: ignore[no-any-return]

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
        construct = self._method(component, api.CONSTRUCT_REQUEST(action))
        call = self._method(component, api.CALL(action))
        if (component, action) in self.layout.runs:
            return self.start(component, action, payload, timeout).response

        def run() -> Any:
            result = call(construct(**payload), timeout=timeout)
            return to_plain(getattr(result, "response", result))

        return self._guarded(component, run)  # type: ignore[no-any-return]

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
        construct = self._method(component, api.CONSTRUCT_MESSAGE(name))
        publish = self._method(component, api.PUBLISH(name))
        fields = value if isinstance(value, Mapping) else {"data": value}
        self._guarded(component, lambda: publish(construct(**fields)))

    # -- ROS actions (the `GoalPort` protocol) --------------------------------------------------------------

    def send_goal(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> str:
        construct = self._method(component, api.CONSTRUCT_GOAL(action))
        send = self._method(component, api.SEND(action))
        handle = self._guarded(component, lambda: send(construct(**payload), timeout=timeout))
        track = GoalTrack(handle, self.feedback_grace, self.server_timeout)
        with self._goals_lock:
            self._goals[(component, action, track.goal_id)] = track
        return track.goal_id

    def _track(self, component: str, action: str, goal: str) -> GoalTrack:
        with self._goals_lock:
            track = self._goals.get((component, action, goal))
        if track is None:
            raise PortCallFailed(f"{component}.{action}: no goal {goal} is followed here")
        return track

    def goal_progress(self, component: str, action: str, goal: str, since: int | None, wait: float) -> GoalProgress:
        return self._track(component, action, goal).progress(since, wait)

    def cancel_goal(self, component: str, action: str, goal: str, timeout: float) -> bool:
        track = self._track(component, action, goal)
        try:
            return bool(track.handle.cancel(timeout=timeout))
        except Exception as exc:  # noqa: BLE001 - every generated error becomes a port error
            raise _port_error(exc) from exc

    def forget_goal(self, component: str, action: str, goal: str) -> None:
        with self._goals_lock:
            track = self._goals.pop((component, action, goal), None)
        if track is not None:
            track.close()

    def close(self) -> None:
        with self._goals_lock:
            tracks, self._goals = list(self._goals.values()), {}
        for track in tracks:
            track.close()
        for instance in self.components.values():
            close = getattr(instance, "close", None)
            if callable(close):
                close()
