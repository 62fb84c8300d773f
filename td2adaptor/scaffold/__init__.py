"""`td2adaptor scaffold`: write a robot's TD (or a fleet's Thing Model) from what the robot shows.

Sources (`ros2graph`, `ros1graph`, `bag`, `listing`) each produce a `graph.Graph`; `graph.select` drops
infrastructure and applies the user's filters; `layout` decides namespaces, names, components and
procedure links; `writer` turns that into the document; `merge` folds it into an existing TD.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.scaffold.graph import Filters, Graph, select
from td2adaptor.scaffold.layout import Group, plan, robot_namespaces
from td2adaptor.scaffold.writer import Schemas, write

__all__ = ["Options", "scaffold"]


@dataclass(frozen=True)
class Options:
    """How to turn a graph into a document (the CLI's options, minus the source)."""

    filters: Filters = field(default_factory=Filters)
    robot_namespaces: tuple[str, ...] = ()
    group: Group = "prefix"
    title: str | None = None
    interfaces: tuple[Path, ...] = ()


def scaffold(graph: Graph, options: Options, diags: Diagnostics) -> dict[str, Any] | None:
    """The TD or Thing Model for `graph`; None (with an error) when nothing is left to describe."""
    endpoints = select(graph, options.filters, diags)
    if diags.has_errors:
        return None
    if not endpoints:
        diags.error(
            "SCF102",
            f"nothing to scaffold: {graph.label} shows no topic, service or action (after the filters)",
            hint="check the namespace/node filters, and that the robot runs on this ROS domain or master",
        )
        return None
    namespaces = robot_namespaces(endpoints, options.robot_namespaces, diags)
    if diags.has_errors:
        return None
    if namespaces:
        kind = "robot namespaces (a fleet: a Thing Model)" if len(namespaces) > 1 else "robot namespace"
        diags.info("SCF105", f"{kind}: {', '.join(namespaces)} written as {{{{robotName}}}}")
    layout = plan(endpoints, namespaces, options.group, diags)
    if graph.complete is not None:
        for p in layout.plans:
            p.endpoint = graph.complete(p.endpoint)
    schemas = Schemas(options.interfaces, diags, graph.definitions)
    return write(layout, schemas, diags, title=options.title or graph.title, label=graph.label)
