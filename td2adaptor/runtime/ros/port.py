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

from collections.abc import Callable, Mapping
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
class GoalEnd:
    """How a ROS action goal ended, as a port tells it (`GoalListener.on_done`).

    `status` is "succeeded", "canceled", "aborted", "rejected" (the server refused it) or "lost" (no end came
    from the server: it went away, it did not take the goal in time, or it forgot it); `result` the result
    message the server sent (None when it sent none); `message` the server's words (actionlib's status text)
    or why the goal is lost; `error` why a goal that never ran did not (PortRejected, PortUnavailable,
    PortTimeout, PortCallFailed; None otherwise).
    """

    status: str
    result: Mapping[str, Any] | None = None
    message: str = ""
    error: PortError | None = None

    def to_json(self) -> dict[str, Any]:
        error = None
        if self.error is not None:
            error = {"kind": type(self.error).__name__, "message": str(self.error)}
        return {"status": self.status, "result": self.result, "message": self.message, "error": error}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> GoalEnd:
        result, error = data.get("result"), data.get("error")
        made: PortError | None = None
        if isinstance(error, Mapping):
            kinds = {k.__name__: k for k in (PortUnavailable, PortTimeout, PortCallFailed, PortRejected)}
            made = kinds.get(str(error.get("kind")), PortCallFailed)(str(error.get("message") or ""))
        return cls(
            str(data.get("status") or "lost"),
            result if isinstance(result, Mapping) else None,
            str(data.get("message") or ""),
            made,
        )


class GoalListener(Protocol):
    """Who follows a goal: told what happens to it, once and in order, by the port's own threads (one call at a
    time per goal; each must return at once: hand the news to your own loop). `on_accepted(goal)` when the
    server took the goal (its id), then `on_status(status)` at each change of a running goal's status
    ("pending", "accepted", "executing", "canceling") and `on_feedback(message)` for each feedback message
    (as plain data), then exactly one `on_done(end)` (a goal refused or lost before acceptance gets only that).
    """

    def on_accepted(self, goal: str) -> None: ...

    def on_status(self, status: str) -> None: ...

    def on_feedback(self, message: Any) -> None: ...

    def on_done(self, end: GoalEnd) -> None: ...


#: the answer to a cancel request: whether the server cancels the goal, or why no answer came
CancelDone = Callable[[bool, "PortError | None"], None]


@runtime_checkable
class GoalPort(Protocol):
    """A robot whose TD actions may be ROS actions: goals followed by callbacks, never by a waiting thread.

    `goal` is the goal id `start_goal` returned (a string). Until the goal's end is told, or `forget_goal`,
    the port keeps the goal's listener; the generated package keeps its feedback (one buffer, the goal's).
    """

    def start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str:
        """Send a goal built from `payload` without waiting for the server; its id. The server must accept it
        within `timeout`. Raises `PortError` only when no goal can be sent (a payload the goal message does not
        take, no such action); everything else comes through `listener`."""
        ...

    def request_cancel(self, component: str, action: str, goal: str, timeout: float, on_done: CancelDone) -> None:
        """Ask the server to cancel the goal without waiting: `on_done(canceling, error)` is told once, by the
        port's threads at most `timeout` seconds from now (inside this call when the port cannot ask at all)."""
        ...

    def forget_goal(self, component: str, action: str, goal: str) -> None:
        """The caller no longer follows the goal: its listener is told nothing more (the goal goes on)."""
        ...


@runtime_checkable
class GoalRejoin(Protocol):
    """A `GoalPort` that can follow a goal it did not send, by its id: one the server accepted from this robot's
    edge node before it restarted, or from another process of a shared fleet that owned the robot (ROS 2's
    action feedback and status are broadcast to every client, and any client may ask a goal's result by its
    id; ROS 1's actionlib broadcasts status, feedback and result with the goal's id)."""

    def rejoin_goal(self, component: str, action: str, goal: str, timeout: float, listener: GoalListener) -> None:
        """Follow goal `goal` without waiting: `listener` is told as for a goal `start_goal` sent (on_accepted
        once the server is there, its status, its feedback from now on, then exactly one on_done: the goal's real
        end, or `lost` with the reason when the server does not know the goal, or no server is there within
        `timeout`). Raises `PortError` only when it cannot be followed at all (no such action, a bad id)."""
        ...


@runtime_checkable
class QuickGoalStart(Protocol):
    """A `GoalPort` that can often send a goal without waiting for anything (ROS 2's generated `start_X` returns
    at once): the engine then starts the goal on its loop, one thread hand-off fewer before the goal is sent,
    and on the call pool only when this says it would have to wait."""

    def try_start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str | None:
        """`start_goal` when it can be done without blocking (no lock to wait for, no reply to wait for); None
        when it cannot, and nothing was sent: the caller calls `start_goal` from a thread that may wait."""
        ...


#: how a call made without waiting ends: `(answer, None)`, or `(None, error)` (a `PortError`; one the robot
#: answered, saying it failed, carries its response)
Answered = Callable[[Any, "PortError | None"], None]


@runtime_checkable
class QuickCall(Protocol):
    """A `RobotPort` that can often make a call without a thread waiting for it (the generated rclpy package's
    `call_<action>_then`): the engine then sends it from its loop and the answer is read and published where
    the port tells it, on the ROS side's thread (no hand-off to the call pool and back). Each returns False,
    and sends nothing, when the call cannot be made so (no server seen yet, the component's calls all in
    flight, a package without it): the caller then makes the `RobotPort` call on a thread that may wait.
    Otherwise `on_done` is told once, from the port's thread (or from inside this call when the answer was
    there at once); it must not block."""

    def try_start(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, on_done: Answered
    ) -> bool:
        """`start` without waiting: `on_done(StartResult, None)`."""
        ...

    def try_query(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        """`query` without waiting: `on_done(response as a dict, None)`."""
        ...

    def try_cancel(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        """`cancel` without waiting: `on_done(response as a dict, None)`."""
        ...

    def try_call(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, on_done: Answered
    ) -> bool:
        """`call` without waiting: `on_done(response as a dict, None)`."""
        ...
