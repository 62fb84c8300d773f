"""A running ROS 2 graph, read with rclpy's graph API (nodes, their topics, services and action servers).

Discovery is gradual: the graph is read until it has not changed for `settle` seconds (at most `wait`), so
a robot whose endpoints are still being announced is not scaffolded half seen.
"""

from __future__ import annotations

import importlib.util
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.scaffold.graph import Endpoint, Graph, Kind, Role, qos_of

NODE_NAME = "td2adaptor_scaffold"

Snapshot = tuple[tuple[str, tuple[tuple[str, str, tuple[str, ...]], ...]], ...]


def _full(name: str, namespace: str) -> str:
    return f"{namespace.rstrip('/')}/{name}"


def _snapshot(node: Any) -> Snapshot:
    from rclpy.action.graph import get_action_server_names_and_types_by_node

    out = []
    for name, namespace in sorted(node.get_node_names_and_namespaces()):
        if name == NODE_NAME or name.startswith("_"):
            continue
        entries: list[tuple[str, str, tuple[str, ...]]] = []
        for role, fetch in (
            ("publisher", node.get_publisher_names_and_types_by_node),
            ("subscriber", node.get_subscriber_names_and_types_by_node),
            ("service", node.get_service_names_and_types_by_node),
        ):
            entries += [(role, topic, tuple(types)) for topic, types in fetch(name, namespace)]
        actions = get_action_server_names_and_types_by_node(node, name, namespace)
        entries += [("action", a, tuple(types)) for a, types in actions]
        out.append((_full(name, namespace), tuple(sorted(entries))))
    return tuple(out)


QosInfo = dict[str, tuple[dict[str, Any] | None, bool]]


def _qos_by_node(node: Any, topic: str, role: str) -> QosInfo:
    """QoS (as `rosv:qos`) and transient-local durability of every `role` endpoint of `topic`, by node."""
    fetch = node.get_publishers_info_by_topic if role == "publisher" else node.get_subscriptions_info_by_topic
    out: QosInfo = {}
    for info in fetch(topic):
        profile = info.qos_profile
        reliability = profile.reliability.name.lower()
        durability = profile.durability.name.lower()
        depth = int(profile.depth) if profile.history.name.lower() == "keep_last" else None
        out.setdefault(
            _full(info.node_name, info.node_namespace),
            (qos_of(reliability, durability, depth), durability == "transient_local"),
        )
    return out


@contextmanager
def opened(
    diags: Diagnostics,
    *,
    wait: float = 10.0,
    settle: float = 2.0,
    domain_id: int | None = None,
    wanted: Callable[[str, str, str], bool] | None = None,
) -> Iterator[Graph | None]:
    """The graph as rclpy sees it, usable inside the `with` (its QoS is read on demand, for the endpoints
    that become affordances, while the node is up); None (SCF101) without rclpy."""
    if importlib.util.find_spec("rclpy") is None:
        diags.error(
            "SCF101",
            "cannot read a ROS 2 graph: rclpy is not installed",
            hint="bash .ci/setup-ros2.sh, or pip install 'td2adaptor[ros2]'",
        )
        yield None
        return
    import rclpy
    from rclpy.context import Context

    context = Context()
    kwargs: dict[str, Any] = {} if domain_id is None else {"domain_id": domain_id}
    rclpy.init(context=context, **kwargs)
    try:
        node = rclpy.create_node(NODE_NAME, context=context, start_parameter_services=False)
        try:
            yield graph_of(node, _settled(node, wait, settle, wanted))
        finally:
            node.destroy_node()  # type: ignore[no-untyped-call]
    finally:
        rclpy.shutdown(context=context)


def _wanted(snap: Snapshot, wanted: Callable[[str, str, str], bool]) -> Snapshot:
    """The part of a snapshot the user asked about (node, role, name)."""
    kept = ((node, tuple(e for e in entries if wanted(node, e[0], e[1]))) for node, entries in snap)
    return tuple((node, entries) for node, entries in kept if entries)


def _settled(node: Any, wait: float, settle: float, wanted: Callable[[str, str, str], bool] | None) -> Snapshot:
    """A snapshot whose wanted part is not empty and has not changed for `settle` seconds (or the last one
    after `wait`): other robots on the domain being stable says nothing about the one asked for."""
    deadline = time.monotonic() + wait
    last: Snapshot | None = None
    since = time.monotonic()
    while True:
        snap = _snapshot(node)
        part = snap if wanted is None else _wanted(snap, wanted)
        now = time.monotonic()
        if part != last:
            last, since = part, now
        elif part and now - since >= settle:
            return snap
        if now >= deadline:
            return snap
        time.sleep(0.05)


def graph_of(node: Any, snap: Snapshot) -> Graph:
    """The endpoints of a snapshot. QoS is not read here: rmw answers each per-topic query by scanning the
    whole graph, so reading it for every topic would cost topics x endpoints; `Graph.complete` reads it,
    once per topic and role, for the endpoints the TD describes."""
    cache: dict[tuple[str, str], QosInfo] = {}

    def complete(ep: Endpoint) -> Endpoint:
        if ep.kind != "topic":
            return ep
        key = (ep.role, ep.name)
        if key not in cache:
            cache[key] = _qos_by_node(node, ep.name, ep.role)
        qos, transient = next((cache[key][n] for n in ep.nodes if n in cache[key]), (None, False))
        return replace(ep, qos=qos, latch=transient and ep.role == "subscriber")

    graph = Graph("the ROS 2 graph", distro="ros2", complete=complete)
    kinds: dict[str, tuple[Kind, Role]] = {
        "action": ("action", "server"),
        "service": ("service", "server"),
        "publisher": ("topic", "publisher"),
        "subscriber": ("topic", "subscriber"),
    }
    for full, entries in snap:
        for role, name, types in entries:
            if types:
                kind, ep_role = kinds[role]
                graph.endpoints.append(Endpoint(kind, name, types[0], ep_role, (full,)))
    return graph
