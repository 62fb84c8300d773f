"""The `td2adaptor types` view: components → services/ROS actions/topics → resolved types, as text or JSON."""

from __future__ import annotations

from typing import Any

from td2adaptor.model import ActionEndpoint, Model, ProcedureRole, ServiceEndpoint, TopicEndpoint


def _rows(model: Model) -> list[dict[str, Any]]:
    rows = []
    for comp in model.components:
        endpoints: tuple[ServiceEndpoint | ActionEndpoint | TopicEndpoint, ...] = (
            *comp.services,
            *comp.actions,
            *comp.topics,
        )
        for ep in endpoints:
            if isinstance(ep, ServiceEndpoint):
                kind = "service"
                role = ep.procedure_role.value if ep.procedure_role is not ProcedureRole.NONE else "client"
            elif isinstance(ep, ActionEndpoint):
                kind, role = "action", "client"  # the adaptor sends goals
            else:
                kind, role = "topic", ep.role.value
            rows.append(
                {
                    "component": comp.name,
                    "name": ep.name,
                    "kind": kind,
                    "role": role,
                    "ros_name": ep.ros_name.binding_form(),
                    "type": ep.type_name,
                    "ros1": model.ros1.get(ep.type_name) is not None,
                    "ros2": model.ros2.get(ep.type_name) is not None,
                }
            )
    return rows


def types_json(model: Model) -> dict[str, Any]:
    return {
        "package": model.package_name,
        "endpoints": _rows(model),
        "messages": {d: [m.name for m in model.types_for(d).messages] for d in ("ros1", "ros2")},
        "actions": {d: [a.name for a in model.types_for(d).actions] for d in ("ros1", "ros2")},
    }


def types_text(model: Model) -> str:
    rows = _rows(model)
    out = [f"package {model.package_name}\n"]
    widths = {k: max([len(str(r[k])) for r in rows] + [0]) for k in ("name", "kind", "role", "ros_name", "type")}
    current = None
    for r in rows:
        if r["component"] != current:
            current = r["component"]
            out.append(f"{current}\n")
        marks = " ".join(f"{d}:{'yes' if r[d] else 'no'}" for d in ("ros1", "ros2"))
        out.append(
            "  "
            + "  ".join(str(r[k]).ljust(widths[k]) for k in ("name", "kind", "role", "ros_name", "type"))
            + f"  {marks}\n"
        )
    return "".join(out)
