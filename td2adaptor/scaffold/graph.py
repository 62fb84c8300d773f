"""The source-independent view of a robot every scaffold source produces: endpoints seen from the robot.

A ROS 2 graph, a ROS 1 master, a bag and a user's listing all become a `Graph` of `Endpoint`s (one per
name, role and type); everything after that (layout, TD writer, merge) never knows where they came from.
Infrastructure (logging, parameters, type descriptions, hidden names) is dropped here, in one place.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from td2adaptor.diagnostics import Diagnostics

Kind = Literal["topic", "service", "action"]
#: what the robot does with the endpoint: publishes / subscribes a topic, serves a service or an action
Role = Literal["publisher", "subscriber", "server"]

#: graph infrastructure left out unless asked for by name (--keep)
INFRASTRUCTURE_TOPICS = frozenset({"/rosout", "/rosout_agg", "/parameter_events", "/tf_static", "/clock"})
_INFRASTRUCTURE_SERVICE_LEAVES = frozenset(
    {
        "describe_parameters",
        "get_parameters",
        "get_parameter_types",
        "list_parameters",
        "set_parameters",
        "set_parameters_atomically",
        "get_type_description",
        "get_loggers",
        "set_logger_level",
        "set_logger_levels",
    }
)

#: the ROS nodes td2adaptor runs itself, by their last name segment: the edge node (`td2adaptor run`:
#: `td2adaptor_edge_<robot>`, or `td2adaptor_edge` for a fleet, `_d<domain>` per extra ROS 2 domain, and the
#: ROS 1 bridge's anonymous `td2adaptor_edge_<robot>_<pid>_<time>`) and the scaffold's own graph reader.
#: Their publishers and subscriptions mirror the robot's (an edge node publishes what the robot subscribes)
#: and are never the robot's interface.
_OWN_NODE = re.compile(r"td2adaptor_(?:edge|scaffold)(?:_\w*)?")


def is_own_node(node: str) -> bool:
    """Whether `node` (a full name) is one td2adaptor runs itself."""
    return _OWN_NODE.fullmatch(node.rsplit("/", 1)[-1]) is not None


@dataclass(frozen=True)
class Endpoint:
    """One topic, service or action of the robot. `type` is canonical (`pkg/msg/Name`, `pkg/srv/Name`)."""

    kind: Kind
    name: str
    type: str
    role: Role
    nodes: tuple[str, ...] = ()
    qos: dict[str, Any] | None = field(default=None, compare=False, hash=False)
    latch: bool = False


@dataclass
class Graph:
    """What one source saw. `label` names the source in the TD's description and in diagnostics."""

    label: str
    endpoints: list[Endpoint] = field(default_factory=list)
    distro: Literal["ros1", "ros2"] = "ros2"
    title: str | None = None
    #: fills in what is costly to read for every endpoint (ROS 2 QoS), for those the TD describes
    complete: Callable[[Endpoint], Endpoint] | None = None
    #: message definitions the source carries (a bag's): canonical name → (where, .msg text)
    definitions: dict[str, tuple[str, str]] = field(default_factory=dict)


def is_infrastructure(kind: Kind, name: str, keep: Iterable[str] = ()) -> bool:
    """Whether `name` is ROS plumbing rather than the robot's interface (hidden names included)."""
    if name in keep:
        return False
    if any(part.startswith("_") for part in name.split("/") if part):
        return True
    if kind == "topic":
        return name in INFRASTRUCTURE_TOPICS
    return kind == "service" and name.rsplit("/", 1)[-1] in _INFRASTRUCTURE_SERVICE_LEAVES


@dataclass(frozen=True)
class Filters:
    """What the user asked to look at: namespaces and nodes (prefixes / full names), name regexes."""

    namespaces: tuple[str, ...] = ()
    nodes: tuple[str, ...] = ()
    include: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    keep: tuple[str, ...] = ()

    def compiled(self, diags: Diagnostics) -> tuple[list[re.Pattern[str]], list[re.Pattern[str]]] | None:
        """The include and exclude patterns; None (and SCF108 each) when one is not a regular expression."""
        out: tuple[list[re.Pattern[str]], list[re.Pattern[str]]] = ([], [])
        ok = True
        for patterns, target in ((self.include, out[0]), (self.exclude, out[1])):
            for pattern in patterns:
                try:
                    target.append(re.compile(pattern))
                except re.error as exc:
                    diags.error("SCF108", f"invalid regular expression {pattern!r}: {exc}")
                    ok = False
        return out if ok else None

    def wanted(self, diags: Diagnostics) -> Callable[[str, str, str], bool] | None:
        """Whether (node, role, name) is asked about: the filters without the type checks of `select`;
        None when an expression is invalid (reported)."""
        patterns = self.compiled(diags)
        if patterns is None:
            return None
        include, exclude = patterns
        nodes = {"/" + n.strip("/") for n in self.nodes}

        def check(node: str, role: str, name: str) -> bool:
            kind: Kind = "topic" if role in ("publisher", "subscriber") else "action" if role == "action" else "service"
            return (
                not is_infrastructure(kind, name, self.keep)
                and (not self.namespaces or any(_under(name, ns) for ns in self.namespaces))
                and (node in nodes if nodes else not is_own_node(node))
                and (not include or any(p.search(name) for p in include))
                and not any(p.search(name) for p in exclude)
            )

        return check


def _under(name: str, namespace: str) -> bool:
    ns = "/" + namespace.strip("/")
    return ns == "/" or name == ns or name.startswith(ns + "/")


def select(graph: Graph, filters: Filters, diags: Diagnostics) -> list[Endpoint]:
    """The endpoints that are the robot's interface and match the filters, merged per (kind, name, role)."""
    patterns = filters.compiled(diags)
    if patterns is None:
        return []
    include, exclude = patterns
    wanted_nodes = {"/" + n.strip("/") for n in filters.nodes}
    merged: dict[tuple[str, str, str], Endpoint] = {}
    types: dict[tuple[str, str], str] = {}
    own: set[str] = set()
    for ep in graph.endpoints:
        if is_infrastructure(ep.kind, ep.name, filters.keep):
            continue
        if ep.nodes and all(is_own_node(n) and n not in wanted_nodes for n in ep.nodes):
            own.update(ep.nodes)
            continue
        if filters.namespaces and not any(_under(ep.name, ns) for ns in filters.namespaces):
            continue
        if wanted_nodes and not wanted_nodes.intersection(ep.nodes):
            continue
        if include and not any(p.search(ep.name) for p in include):
            continue
        if any(p.search(ep.name) for p in exclude):
            continue
        seen = types.setdefault((ep.kind, ep.name), ep.type)
        if seen != ep.type:
            diags.warning("SCF106", f"{ep.name} has several types ({seen}, {ep.type}): {seen} is used")
            continue
        key = (ep.kind, ep.name, ep.role)
        old = merged.get(key)
        if old is None:
            merged[key] = ep
        else:
            nodes = tuple(sorted(set(old.nodes) | set(ep.nodes)))
            merged[key] = Endpoint(ep.kind, ep.name, ep.type, ep.role, nodes, old.qos or ep.qos, old.latch or ep.latch)
    if own:
        diags.info(
            "SCF115",
            f"left out td2adaptor's own node{'s' * (len(own) > 1)} {', '.join(sorted(own))}: an edge node "
            "publishes what the robot subscribes and subscribes what it publishes",
            hint="--node NAME keeps one",
        )
    return fold_actionlib(list(merged.values()))


#: the topics of a ROS 1 (actionlib) action server `X`: leaf -> (the server's role, type suffix or full type)
_ACTIONLIB: dict[str, tuple[Role, str]] = {
    "goal": ("subscriber", "ActionGoal"),
    "cancel": ("subscriber", "actionlib_msgs/msg/GoalID"),
    "status": ("publisher", "actionlib_msgs/msg/GoalStatusArray"),
    "feedback": ("publisher", "ActionFeedback"),
    "result": ("publisher", "ActionResult"),
}


def fold_actionlib(endpoints: Sequence[Endpoint]) -> list[Endpoint]:
    """ROS 1 actions: the five topics of an actionlib server (`X/goal` typed `pkg/msg/NameActionGoal`,
    `X/cancel`, `X/status`, `X/feedback`, `X/result`) become one action `X` of type `pkg/action/Name`."""
    topics = {(e.name, e.role): e for e in endpoints if e.kind == "topic"}
    folded: set[tuple[str, str]] = set()
    actions: list[Endpoint] = []
    for goal in endpoints:
        if goal.kind != "topic" or goal.role != "subscriber" or not goal.name.endswith("/goal"):
            continue
        package, _, message = goal.type.partition("/msg/")
        if not message.endswith("ActionGoal"):
            continue
        base, name = goal.name[: -len("/goal")], message.removesuffix("ActionGoal")
        keys = {(f"{base}/{leaf}", role) for leaf, (role, _) in _ACTIONLIB.items()}
        found = {leaf: topics.get((f"{base}/{leaf}", role)) for leaf, (role, _) in _ACTIONLIB.items()}
        expected = {
            leaf: want if "/" in want else f"{package}/msg/{name}{want}" for leaf, (_, want) in _ACTIONLIB.items()
        }
        if all(ep is not None and ep.type == expected[leaf] for leaf, ep in found.items()):
            folded |= keys
            actions.append(Endpoint("action", base, f"{package}/action/{name}", "server", goal.nodes))
    kept = [e for e in endpoints if e.kind != "topic" or (e.name, e.role) not in folded]
    return sorted(kept + actions, key=lambda e: (e.name, e.kind, e.role))


def node_namespace(node: str) -> str:
    """`/ns/sub` of node `/ns/sub/name` (`/` for a node in the root namespace)."""
    return node.rsplit("/", 1)[0] or "/"


def qos_of(reliability: str | None, durability: str | None, depth: int | None) -> dict[str, Any] | None:
    """A `rosv:qos` object with only what differs from the binding's defaults (None when nothing does)."""
    qos: dict[str, Any] = {}
    if reliability == "best_effort":
        qos["reliability"] = reliability
    if durability == "transient_local":
        qos["durability"] = durability
    if depth is not None and 0 < depth != 10:
        qos["depth"] = depth
    return qos or None


def sorted_names(names: Sequence[str]) -> tuple[str, ...]:
    return tuple(sorted(set(names)))
