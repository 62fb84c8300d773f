"""A `RobotPort` onto the generated rclpy or rospy component classes: how the edge node reaches real ROS.

The generated packages (issue 3) offer, per component, `construct_<action>_Msg(**fields)`,
`call_<action>(request, *, timeout)` (procedure runs return `Started(mission_id, response)`, queries and
cancels accept `mission_id=`), `get_<property>_value(timeout=)`, `construct_<property>_Msg` /
`publish_<property>_Msg`, and raise `ServiceUnavailable` / `CallTimeout` / `CallFailed` / `NoMessage`.
This adapter turns dicts into those calls and messages back into dicts, and maps the errors onto
`PortError`s. One lock per component: the generated clients are used from the engine's mission threads.

Values use the field names of the robot's own ROS version, as the event schemas and the robot's published
TD declare them: a ROS 1 time or duration is `{"secs": ..., "nsecs": ...}`, a ROS 2 one `{"sec": ...,
"nanosec": ...}` (the generated rospy constructors accept either spelling on the way in).
Only the standard library and `td2adaptor.model` are imported: the ROS 1 bridge runs this module under a
ROS 1 interpreter.
"""

from __future__ import annotations

import importlib
import math
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from td2adaptor.model import Model, ProcedureRole
from td2adaptor.runtime.port import (
    NoValue,
    PortCallFailed,
    PortError,
    PortTimeout,
    PortUnavailable,
    StartResult,
)


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
    fields = getattr(value, "get_fields_and_field_types", None)
    if callable(fields):  # rosidl message
        return {name: to_plain(getattr(value, name)) for name in fields()}
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
    message = str(exc).strip()  # may be empty: the error event then says the kind in words (runtime/words.py)
    if "ServiceUnavailable" in names:
        return PortUnavailable(message)
    if "CallTimeout" in names:
        return PortTimeout(message)
    if "NoMessage" in names:
        return NoValue(message)
    return PortCallFailed(message, response=plain if isinstance(plain, Mapping) else None)


@dataclass(frozen=True)
class Layout:
    """What the port needs to know of a model: its component classes and its procedure run actions."""

    components: tuple[str, ...]
    runs: frozenset[tuple[str, str]] = frozenset()

    @classmethod
    def of(cls, model: Model) -> Layout:
        runs = {(c.name, s.name) for c in model.components for s in c.services if s.procedure_role is ProcedureRole.RUN}
        return cls(tuple(c.name for c in model.components), frozenset(runs))

    def to_json(self) -> dict[str, Any]:
        return {"components": list(self.components), "runs": sorted([c, a] for c, a in self.runs)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Layout:
        runs: Iterable[Any] = data.get("runs") or ()
        return cls(tuple(str(c) for c in data["components"]), frozenset((str(c), str(a)) for c, a in runs))


class GeneratedPort:
    """Drive one robot through a generated adaptor package (`package` is the imported module or its name).

    `model` is the compiled model (or just its `Layout`). `distro` "ros2" builds components as
    `Cls(node, robot_name, ...)`, "ros1" as `Cls(robot_name, ...)`.
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
    ) -> None:
        if distro not in ("ros1", "ros2"):
            raise ValueError(f"distro must be 'ros1' or 'ros2', not {distro!r}")
        if distro == "ros2" and node is None:
            raise ValueError("a ROS 2 port needs the rclpy node that owns its clients (node=...)")
        self.layout = model if isinstance(model, Layout) else Layout.of(model)
        self.robot_name = robot_name
        module = importlib.import_module(package) if isinstance(package, str) else package
        self.components: dict[str, Any] = {}
        self._locks: dict[str, threading.Lock] = {}
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
            self._locks[name] = threading.Lock()

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
        construct = self._method(component, f"construct_{action}_Msg")
        call = self._method(component, f"call_{action}")

        def run() -> StartResult:
            result = call(construct(**payload), timeout=timeout)
            if hasattr(result, "mission_id") and hasattr(result, "response"):
                mid = result.mission_id
                return StartResult(to_plain(result.response), int(mid) if mid is not None else None)
            return StartResult(to_plain(result))

        return self._guarded(component, run)  # type: ignore[no-any-return]

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        call = self._method(component, f"call_{action}")
        return self._guarded(component, lambda: to_plain(call(mission_id=mission_id, timeout=timeout)))  # type: ignore[no-any-return]

    def cancel(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        return self.query(component, action, mission_id, timeout)

    def call(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Mapping[str, Any]:
        construct = self._method(component, f"construct_{action}_Msg")
        call = self._method(component, f"call_{action}")
        if (component, action) in self.layout.runs:
            return self.start(component, action, payload, timeout).response

        def run() -> Any:
            result = call(construct(**payload), timeout=timeout)
            return to_plain(getattr(result, "response", result))

        return self._guarded(component, run)  # type: ignore[no-any-return]

    def read_property(self, component: str, name: str, timeout: float) -> Any:
        get = self._method(component, f"get_{name}_value")
        return self._guarded(component, lambda: to_plain(get(timeout=timeout)))

    def write_property(self, component: str, name: str, value: Any) -> None:
        construct = self._method(component, f"construct_{name}_Msg")
        publish = self._method(component, f"publish_{name}_Msg")
        fields = value if isinstance(value, Mapping) else {"data": value}
        self._guarded(component, lambda: publish(construct(**fields)))

    def close(self) -> None:
        for instance in self.components.values():
            close = getattr(instance, "close", None)
            if callable(close):
                close()
