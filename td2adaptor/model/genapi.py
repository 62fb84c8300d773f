"""The generated API: the name and shape of every member a generated component class offers, in one place.

The rclpy and rospy generators, their templates (as the Jinja global `api`) and the mROS backend's hooks spell
the names from here; the edge node's generated port (`runtime/ros/genport.py`, which the ROS 1 bridge runs
under ROS 1's interpreter: this module imports the standard library only) calls them by the same names; and
`clashes` is the one check that a component's names are distinct. A test (tests/backends/test_python_twins.py)
holds both generated packages to these shapes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

#: the Python backends that generate component classes
PYTHON = ("rclpy", "rospy")


@dataclass(frozen=True)
class Method:
    """One kind of generated method: `pattern` with the affordance's name for `{}`, its parameters (`shape`:
    positional ones, then "*" and the keyword-only ones; "**fields" stands for one keyword per message field),
    and the backends that generate it."""

    pattern: str
    shape: tuple[str, ...]
    backends: tuple[str, ...] = PYTHON

    def __call__(self, name: str) -> str:
        """The method's name for the affordance `name`."""
        return self.pattern.format(name)


# -- per TD action bound to a ROS service
CONSTRUCT_REQUEST = Method("construct_{}_Msg", ("*", "**fields"))
#: a procedure's query and cancel take `mission_id` too (before `timeout`) when their request carries it
CALL = Method("call_{}", ("request", "*", "timeout"))
CALL_ASYNC = Method("call_{}_async", ("request", "*", "timeout"), ("rclpy",))
MISSION_ID = "mission_id"

# -- per TD action bound to a ROS 2 action
CONSTRUCT_GOAL = Method("construct_{}_Goal", ("*", "**fields"))
SEND = Method("send_{}", ("goal", "*", "timeout"))
SEND_ASYNC = Method("send_{}_async", ("goal", "*", "timeout"), ("rclpy",))
START = Method(
    "start_{}", ("goal", "*", "on_accepted", "on_status", "on_feedback", "on_done", "timeout", "feedback_grace")
)

# -- per subscribed property
GET = Method("get_{}_value", ("*", "timeout"))
ON = Method("on_{}", ("callback",))
ON_SERIALIZED = Method("on_{}_serialized", ("callback",))

# -- per published property
CONSTRUCT_MESSAGE = Method("construct_{}_Msg", ("*", "**fields"))
PUBLISH = Method("publish_{}_Msg", ("msg",))

# -- once per component
#: the latest message of a component's only subscribed property (when it has exactly one)
GET_ONLY = Method("get_value", ("*", "timeout"))
REGISTER = Method("register", ())
CLOSE = Method("close", (), ("rospy",))  # ROS 2 has no connections to release
#: attributes every component has besides its methods (`node`: the rclpy node)
ATTRIBUTES = ("robot_name", "timeout", "wait_timeout", "node")

SERVICE = (CONSTRUCT_REQUEST, CALL, CALL_ASYNC)
ACTION = (CONSTRUCT_GOAL, SEND, SEND_ASYNC, START)
SUBSCRIBER = (GET, ON, ON_SERIALIZED)
PUBLISHER = (CONSTRUCT_MESSAGE, PUBLISH)

#: what the handle `send_X` and `start_X` return offers in both packages (the generated port follows a goal
#: through it; it reads rospy's `reason` where there is one)
GOAL_HANDLE = (
    "goal_id",
    "status",
    "done",
    "feedback_received",
    "feedback",
    "result",
    "cancel",
    "request_cancel",
    "on_feedback",
)


def members(
    services: Iterable[str] = (),
    actions: Iterable[str] = (),
    subscribers: Iterable[str] = (),
    publishers: Iterable[str] = (),
) -> list[tuple[str, str]]:
    """Every member of a component with these affordances, as (name, whose): the methods of either Python
    package, so that one TD gives both packages the same names (or both refuse it)."""
    subscribers = list(subscribers)
    out = [(m.pattern, "a member every component has") for m in (REGISTER, CLOSE)]
    out += [(name, "a member every component has") for name in ATTRIBUTES]
    for group, names in ((SERVICE, services), (ACTION, actions), (SUBSCRIBER, subscribers), (PUBLISHER, publishers)):
        out += [(method(name), name) for name in names for method in group]
    if len(subscribers) == 1:
        out.append((GET_ONLY.pattern, "the only subscribed property"))
    return out


def clashes(
    services: Iterable[str] = (),
    actions: Iterable[str] = (),
    subscribers: Iterable[str] = (),
    publishers: Iterable[str] = (),
) -> list[tuple[str, str, str]]:
    """The one clash check: (member, whose, whose it already is) for each generated name given twice, e.g. an
    action and a published property both named `go` (construct_go_Msg), or a service `go_async` beside `go`."""
    seen: dict[str, str] = {}
    found = []
    for name, owner in members(services, actions, subscribers, publishers):
        if name in seen:
            found.append((name, owner, seen[name]))
        else:
            seen[name] = owner
    return found
