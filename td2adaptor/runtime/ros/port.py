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

#: the ROS action goal states a port reports: ROS 2's GoalStatus words, and actionlib's pending, rejected and
#: lost (the goal ended without a result: the server forgot it, or went away)
GOAL_STATES = (
    "unknown",
    "pending",
    "accepted",
    "executing",
    "canceling",
    "succeeded",
    "canceled",
    "aborted",
    "rejected",
    "lost",
)


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


class PortRejected(PortError):
    """A ROS action server refused the goal (it never ran)."""

    reason = "rejected"


class NoValue(PortError):
    """A subscribed property has not received any message yet."""


class RosSetupError(Exception):
    """ROS, the generated package or a robot cannot be reached; the message says what to do. (Not a
    `PortError`: no call failed, the ports cannot be made; raised by node/roslink.py and by the ROS 1 bridge.)"""


class StalePackage(RosSetupError):
    """The generated package was generated from another model than the Thing Description `run` was given
    (its recorded hash differs, or it records none: generated before packages did). `package` and `distro`
    ("ros1", "ros2") name it; the message says what differs."""

    def __init__(self, message: str, package: str = "", distro: str = "") -> None:
        super().__init__(message)
        self.package = package
        self.distro = distro


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


@dataclass(frozen=True)
class GoalProgress:
    """What happened to a ROS action goal since the caller last asked.

    `feedback` are the feedback messages received after the first `since` ones (as dicts, in order),
    `received` how many arrived in all, `status` one of GOAL_STATES; once `done`, `result` is the result
    message the server sent (None when it sent none) and `message` the server's words (actionlib's status
    text) or why the goal was lost.
    """

    feedback: tuple[Any, ...]
    received: int
    status: str
    done: bool = False
    result: Mapping[str, Any] | None = None
    message: str = ""

    def to_json(self) -> dict[str, Any]:
        return {
            "feedback": list(self.feedback),
            "received": self.received,
            "status": self.status,
            "done": self.done,
            "result": self.result,
            "message": self.message,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> GoalProgress:
        result = data.get("result")
        return cls(
            tuple(data.get("feedback") or ()),
            int(data.get("received") or 0),
            str(data.get("status") or "unknown"),
            bool(data.get("done")),
            result if isinstance(result, Mapping) else None,
            str(data.get("message") or ""),
        )


@runtime_checkable
class GoalPort(Protocol):
    """A robot whose TD actions may be ROS actions: goals, their feedback, result and cancel.

    `goal` is the goal id the port returned from `send_goal` (a hex string). A port forgets a goal when told
    to, or when it is closed; until then `goal_progress` keeps every feedback message (up to a bound).
    """

    def send_goal(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> str:
        """Send a goal built from `payload`; its id once accepted (`PortRejected` when the server refuses)."""
        ...

    def goal_progress(self, component: str, action: str, goal: str, since: int | None, wait: float) -> GoalProgress:
        """Feedback after the first `since` messages (None: none, the status only), waiting at most `wait`
        seconds for some to arrive or for the goal to end."""
        ...

    def cancel_goal(self, component: str, action: str, goal: str, timeout: float) -> bool:
        """Ask the server to cancel the goal; whether it accepted to."""
        ...

    def forget_goal(self, component: str, action: str, goal: str) -> None:
        """The caller no longer follows the goal."""
        ...
