"""What the runtime needs from a robot: the `RobotPort` protocol.

The engine never sees ROS. An adapter onto the generated rclpy/rospy component classes (or the in-process
simulation in `simport`) implements this protocol; everything crossing it is JSON-compatible data (dicts,
lists, str, int, float, bool, None), so adapters stay thin: convert a dict to the request message, call the
generated method, convert the response message back to a dict, and map the generated errors onto the
`PortError` subclasses below (anything else raised counts as `PortCallFailed`).

Names are the model's: `component` is `Component.name` (e.g. "GoToComponent"), `action` the TD affordance
name of the service to call (the run, query or cancel action itself), `name` a property's affordance name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable


class PortError(Exception):
    """A robot call that failed. `response` is the robot's answer when there was one (as a dict).

    The generated components raise `CallFailed` when a procedure response says `result: error` (a refused
    run, a query of an unknown mission); the adapter passes its response on here, so the engine reads it as
    the robot's answer (rejected, failed) rather than as a broken connection.
    """

    reason = "call-failed"

    def __init__(self, message: str = "", *, response: Mapping[str, Any] | None = None) -> None:
        super().__init__(message)
        self.response = response


class PortUnavailable(PortError):
    """The service or topic is not there (robot down, node not started)."""

    reason = "unreachable"


class PortTimeout(PortError):
    """No response within the timeout; the call may or may not have taken effect."""

    reason = "unreachable"


class PortCallFailed(PortError):
    """The call was made and failed (remote exception, conversion error, ...)."""


class NoValue(PortError):
    """A subscribed property has not received any message yet."""


@dataclass(frozen=True)
class StartResult:
    """Answer to starting a procedure: the robot's response and the mission id it assigned (None if none)."""

    response: Mapping[str, Any]
    mission_id: int | None = None


@dataclass(frozen=True)
class PortInfo:
    """Optional description an adapter may give (shown in logs)."""

    name: str
    details: Mapping[str, Any] = field(default_factory=dict)


@runtime_checkable
class RobotPort(Protocol):
    """One robot, as the event engine drives it. Methods may be called from several threads at once."""

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> StartResult:
        """Call the run action `action` of a procedure with the request fields in `payload`."""
        ...

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        """Call the query action `action` for `mission_id` (-1: the last one); the response as a dict."""
        ...

    def cancel(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        """Call the cancel action `action` for `mission_id` (-1: the last one); the response as a dict."""
        ...

    def call(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Mapping[str, Any]:
        """Call a plain (non-procedure) action; the response as a dict."""
        ...

    def read_property(self, component: str, name: str, timeout: float) -> Any:
        """The latest value of a subscribed property (raises `NoValue` if none arrived yet)."""
        ...

    def write_property(self, component: str, name: str, value: Any) -> None:
        """Publish `value` on a publisher property."""
        ...
