"""A running ROS 2 graph, read with rclpy's graph API (nodes, their topics, services and action servers).

Discovery is gradual: the graph is read until it has not changed for `settle` seconds (at most `wait`), so
a robot whose endpoints are still being announced is not scaffolded half seen.
"""

from __future__ import annotations

import importlib.util
import time
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.scaffold.graph import Endpoint, Graph, qos_of

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


def _qos(node: Any, topic: str, role: str, full: str) -> tuple[dict[str, Any] | None, bool]:
    fetch = node.get_publishers_info_by_topic if role == "publisher" else node.get_subscriptions_info_by_topic
    for info in fetch(topic):
        if _full(info.node_name, info.node_namespace) != full:
            continue
        profile = info.qos_profile
        reliability = profile.reliability.name.lower()
        durability = profile.durability.name.lower()
        depth = int(profile.depth) if profile.history.name.lower() == "keep_last" else None
        return qos_of(reliability, durability, depth), durability == "transient_local"
    return None, False


def read(diags: Diagnostics, *, wait: float = 10.0, settle: float = 1.0, domain_id: int | None = None) -> Graph | None:
    """The graph as rclpy sees it; None (SCF101) without rclpy."""
    if importlib.util.find_spec("rclpy") is None:
        diags.error(
            "SCF101",
            "cannot read a ROS 2 graph: rclpy is not installed",
            hint="bash .ci/setup-ros2.sh, or pip install 'td2adaptor[ros2]'",
        )
        return None
    import rclpy
    from rclpy.context import Context

    context = Context()
    kwargs: dict[str, Any] = {} if domain_id is None else {"domain_id": domain_id}
    rclpy.init(context=context, **kwargs)
    try:
        node = rclpy.create_node(NODE_NAME, context=context, start_parameter_services=False)
        try:
            snap = _settled(node, wait, settle)
            return _graph(node, snap)
        finally:
            node.destroy_node()  # type: ignore[no-untyped-call]
    finally:
        rclpy.shutdown(context=context)


def _settled(node: Any, wait: float, settle: float) -> Snapshot:
    deadline = time.monotonic() + wait
    last: Snapshot | None = None
    since = time.monotonic()
    while True:
        snap = _snapshot(node)
        now = time.monotonic()
        if snap != last:
            last, since = snap, now
        elif snap and now - since >= settle:
            return snap
        if now >= deadline:
            return snap
        time.sleep(0.05)


def _graph(node: Any, snap: Snapshot) -> Graph:
    graph = Graph("the ROS 2 graph", distro="ros2")
    for full, entries in snap:
        for role, name, types in entries:
            if not types:
                continue
            if role == "action":
                graph.endpoints.append(Endpoint("action", name, types[0], "server", (full,)))
            elif role == "service":
                graph.endpoints.append(Endpoint("service", name, types[0], "server", (full,)))
            else:
                qos, transient = _qos(node, name, role, full)
                latch = transient and role == "subscriber"
                graph.endpoints.append(Endpoint("topic", name, types[0], role, (full,), qos, latch))  # type: ignore[arg-type]
    return graph
