"""The generated API: the name and shape of every member a generated component class offers, in one place.

The rclpy and rospy generators, their templates (as the Jinja global `api`) and the mROS backend's hooks spell
the names from here; the edge node's generated port (`runtime/ros/genport.py`, which the ROS 1 bridge runs
under ROS 1's interpreter: this module imports the standard library only) calls them by the same names; and
`clashes` is the one check that a component's names are distinct. Each generated package also records its
ports and the hash of its model (`record_source`), which the generated port checks before it drives it. A test
(tests/backends/test_python_twins.py) holds both generated packages to these shapes.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from td2adaptor.model import Model

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
#: the call without waiting: `on_done(answer, error)` later, on the ROS side's thread; False when it cannot be
#: made so (then `call_<action>`); a procedure's query and cancel take `mission_id` too
CALL_THEN = Method("call_{}_then", ("request", "*", "on_done", "timeout"), ("rclpy",))
MISSION_ID = "mission_id"

# -- per TD action bound to a ROS 2 action
CONSTRUCT_GOAL = Method("construct_{}_Goal", ("*", "**fields"))
SEND = Method("send_{}", ("goal", "*", "timeout"))
SEND_ASYNC = Method("send_{}_async", ("goal", "*", "timeout"), ("rclpy",))
START = Method(
    "start_{}", ("goal", "*", "on_accepted", "on_status", "on_feedback", "on_done", "timeout", "feedback_grace")
)
#: follow a goal the server accepted from another client (a restarted or another edge process) by its id
REJOIN = Method(
    "rejoin_{}", ("goal_id", "*", "on_accepted", "on_status", "on_feedback", "on_done", "timeout", "feedback_grace")
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
#: {TD action: whether its server is there now}, for every action of the component (its presence)
SERVERS_READY = Method("servers_ready", ())
#: attributes every component has besides its methods (`node`: the rclpy node)
ATTRIBUTES = ("robot_name", "timeout", "wait_timeout", "node")

SERVICE = (CONSTRUCT_REQUEST, CALL, CALL_ASYNC, CALL_THEN)
ACTION = (CONSTRUCT_GOAL, SEND, SEND_ASYNC, START, REJOIN)
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
    out = [(m.pattern, "a member every component has") for m in (REGISTER, CLOSE, SERVERS_READY)]
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


# -- what a generated package records of its model (`td2adaptor run` checks it against the TD)

#: the module of a generated package that holds `MODEL_HASH` and `PORTS`
RECORD = "ports"
#: model members a generated package does not depend on for its ports: text, data schemas (the edge node reads
#: those from the TD itself), the thing's metadata and the package's name (`--package-name` may rename it)
_UNHASHED = frozenset({"text", "input_schema", "output_schema", "schema", "thing", "package_name"})


def ports(model: Model) -> dict[str, dict[str, list[str]]]:
    """Per component: its affordances by kind, in TD order (the table a generated package carries)."""
    return {
        c.name: {
            "services": [s.name for s in c.services],
            "actions": [a.name for a in c.actions],
            "subscribers": [t.name for t in c.subscribers],
            "publishers": [t.name for t in c.publishers],
        }
        for c in model.components
    }


def _plain(value: Any) -> Any:
    """`value` as JSON data for the hash: dataclasses by their compared fields (no source pointers, origins or
    comments: no path reaches the hash), enums by value, sets sorted."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: _plain(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if f.compare and f.name not in _UNHASHED
        }
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (frozenset, set)):
        return sorted(_plain(v) for v in value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def model_hash(model: Model, distro: str) -> str:
    """The hash of what a `distro` package generated from `model` depends on: its components (names, ROS names,
    types, roles, QoS, procedures) and the interface types of that ROS version. Neither paths nor time."""
    data = {"components": _plain(model.components), "types": _plain(model.types_for(distro))}
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=True, default=str)
    return "sha256:" + hashlib.sha256(text.encode("utf-8")).hexdigest()


def record_source(model: Model, distro: str) -> str:
    """The `ports` module of a generated `distro` package: its ports and the hash of its model."""
    lines = ["PORTS: dict[str, dict[str, list[str]]] = {"]
    for component, kinds in ports(model).items():
        lines.append(f"    {json.dumps(component)}: {{")
        for kind, names in kinds.items():
            items = "".join(f"\n            {json.dumps(n)}," for n in names)
            lines.append(f"        {json.dumps(kind)}: [{items}\n        ]," if names else f'        "{kind}": [],')
        lines.append("    },")
    lines.append("}")
    if len(lines) == 2:
        lines = ["PORTS: dict[str, dict[str, list[str]]] = {}"]
    return (
        '"""What this package was generated from: its ports and the hash of the td2adaptor model (`td2adaptor run`\n'
        "checks both against the Thing Description it is given and refuses a package generated from another one).\n"
        "\n"
        'Generated by td2adaptor; do not edit.\n"""\n'
        "\n"
        f"MODEL_HASH = {json.dumps(model_hash(model, distro))}\n" + "\n".join(lines) + "\n"
    )
