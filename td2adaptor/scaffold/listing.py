"""A listing: the robot's names and types written by the user in a short YAML file, for a robot that is not
running (its interface packages, given with --interfaces, supply the rest):

    title: Robotnik RB-1                 # optional
    publishes:                           # topics the robot publishes (read properties)
      /rb1_base_a/robot_local_control/state: robot_local_control_msgs/msg/Status
    subscribes:                          # topics the robot listens to (write-only properties)
      /door1/door_controller/command: {type: std_msgs/Float64, latch: true, qos: {depth: 1}}
    services:                            # services the robot serves (actions)
      /rb1_base_a/robot_local_control/NavigationComponent/GoToComponent/add: robot_local_control_msgs/GoToPetition
    actions:                             # ROS 2 action servers
      /rb1_base_a/fibonacci: test_msgs/action/Fibonacci

A value is a type, or a mapping with `type` (and, for topics, `latch` and `qos`). Types may be spelled
the ROS 1 way; they are made canonical.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.rostypes.names import Kind as TypeKind
from td2adaptor.rostypes.names import normalize_type_name
from td2adaptor.scaffold.graph import Endpoint, Graph, Kind, Role

_SECTIONS: dict[str, tuple[Kind, Role, TypeKind]] = {
    "publishes": ("topic", "publisher", "msg"),
    "subscribes": ("topic", "subscriber", "msg"),
    "services": ("service", "server", "srv"),
    "actions": ("action", "server", "action"),
}
_QOS_KEYS = frozenset({"reliability", "durability", "history", "depth"})


def _entry(section: str, name: Any, value: Any, diags: Diagnostics) -> Endpoint | None:
    kind, role, type_kind = _SECTIONS[section]
    spec = value if isinstance(value, dict) else {"type": value}
    raw = spec.get("type")
    canonical = normalize_type_name(raw, type_kind) if isinstance(raw, str) else None
    where = f"{section}/{name}"
    if not isinstance(name, str) or not name.startswith("/") or canonical is None:
        diags.error(
            "SCF111",
            f"{where}: needs an absolute ROS name and a type such as pkg/{type_kind}/Name (got {raw!r})",
        )
        return None
    qos = spec.get("qos")
    if qos is not None and (not isinstance(qos, dict) or not set(qos) <= _QOS_KEYS):
        diags.error("SCF111", f"{where}: qos takes {', '.join(sorted(_QOS_KEYS))}")
        return None
    latch = spec.get("latch", False)
    if not isinstance(latch, bool) or set(spec) - {"type", "qos", "latch"}:
        diags.error("SCF111", f"{where}: an entry takes type, qos and latch (latch true or false)")
        return None
    return Endpoint(kind, name, canonical, role, (), dict(qos) if qos else None, latch)


def read(path: Path, diags: Diagnostics) -> Graph | None:
    """The listing as a graph; None (SCF100/SCF111) when it is not one."""
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        diags.error("SCF100", f"cannot read the listing {path}: {exc}")
        return None
    if not isinstance(doc, dict) or not set(doc) <= {*_SECTIONS, "title"}:
        keys = sorted(doc) if isinstance(doc, dict) else type(doc).__name__
        diags.error("SCF100", f"{path}: a listing is a mapping of title, {', '.join(_SECTIONS)} (got {keys})")
        return None
    title = doc.get("title")
    graph = Graph(f"the listing {path.name}", title=title if isinstance(title, str) else None)
    for section in _SECTIONS:
        entries = doc.get(section) or {}
        if not isinstance(entries, dict):
            diags.error("SCF111", f"{section}: a mapping of ROS names to types")
            continue
        for name, value in entries.items():
            endpoint = _entry(section, name, value, diags)
            if endpoint is not None:
                graph.endpoints.append(endpoint)
    return None if diags.has_errors else graph
