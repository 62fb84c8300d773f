"""`td2adaptor migrate`: rewrite reference-dialect TDs and legacy RosClasses configs in the td2adaptor binding.

The result compiles to the same canonical model as the input (a test proves it): names, types, grouping,
QoS and procedure linkage are written out explicitly from the model, schemas and texts are kept verbatim.
Defects that are purely formal (pre-REC @context, epoch-string dates, links without href, empty hrefs,
`application/xml` content types) are repaired, each with an info diagnostic; data-schema defects are not
touched, since only the user can know the intended schema.
"""

from __future__ import annotations

import datetime
from collections.abc import Mapping
from typing import Any

from td2adaptor.diagnostics import Diagnostics, pointer_join
from td2adaptor.frontend.extract import AFFORDANCE_KINDS, REFERENCE_CLASS_KEY, form_dialect
from td2adaptor.model import Model, QoS, Role, ServiceEndpoint, TopicEndpoint

TD11_CONTEXT = "https://www.w3.org/2022/wot/td/v1.1"
TD10_CONTEXT = "https://www.w3.org/2019/wot/td/v1"
ROSV_CONTEXT = "https://td2adaptor.dev/ns/rosv/v1"
_PRE_REC_CONTEXTS = {"http://www.w3.org/ns/td", "https://www.w3.org/ns/td"}


def migrate(src: Mapping[str, Any], model: Model, diags: Diagnostics, *, legacy: bool) -> dict[str, Any]:
    """The binding TD for the TD `src` (made from RosClasses files when `legacy`), whose compiled model is
    `model`. It takes the TD, not the compiler's input: the front end stands below the compiler."""
    endpoints: dict[str, ServiceEndpoint | TopicEndpoint] = {}
    component_of: dict[str, str] = {}
    for comp in model.components:
        eps: list[ServiceEndpoint | TopicEndpoint] = [*comp.services, *comp.topics]
        for ep in eps:
            endpoints[ep.pointer] = ep
            component_of[ep.pointer] = comp.name
    procedures = {p.run: p for c in model.components for p in c.procedures}
    out: dict[str, Any] = {"@context": _context(src.get("@context"), diags)}
    if legacy:
        out["@type"] = "Thing"
    for key, value in src.items():
        if key == "@context":
            continue
        if key == "ros:masterURI":
            out["rosv:masterURI"] = value
        elif key in ("created", "modified", "lastModified"):
            target = "modified" if key == "lastModified" else key
            out[target] = _date(value, key, diags)
        elif key == "links" and isinstance(value, list):
            kept = [link for link in value if isinstance(link, dict) and link.get("href")]
            if len(kept) != len(value):
                diags.info("MIG710", "links without href dropped", "/links")
            if kept:
                out["links"] = kept
        elif key in AFFORDANCE_KINDS and isinstance(value, dict):
            out[key] = {
                name: _affordance(aff, pointer_join("", key, name), endpoints, component_of, procedures, legacy)
                for name, aff in value.items()
            }
        else:
            out[key] = value
    out.setdefault("title", model.thing.title)
    return out


def _context(ctx: Any, diags: Diagnostics) -> list[Any]:
    items = ctx if isinstance(ctx, list) else [ctx] if ctx is not None else []
    strings: list[Any] = []
    objects: list[Any] = []
    for item in items:
        if isinstance(item, str):
            if item in _PRE_REC_CONTEXTS:
                diags.info(
                    "MIG711",
                    f"pre-recommendation @context {item!r} replaced by {TD11_CONTEXT!r}",
                    "/@context",
                )
                continue
            if item not in (TD11_CONTEXT, ROSV_CONTEXT):
                strings.append(item)
        elif isinstance(item, dict):
            cleaned = {k: v for k, v in item.items() if k != "ros"}
            if cleaned:
                objects.append(cleaned)
    head = [TD11_CONTEXT] if TD10_CONTEXT not in strings else [TD10_CONTEXT, TD11_CONTEXT]
    rest = [s for s in strings if s != TD10_CONTEXT]
    return [*head, *rest, ROSV_CONTEXT, *objects]


def _date(value: Any, key: str, diags: Diagnostics) -> Any:
    if isinstance(value, str) and value.isdigit():
        stamp = datetime.datetime.fromtimestamp(int(value), tz=datetime.timezone.utc)
        iso = stamp.strftime("%Y-%m-%dT%H:%M:%SZ")
        diags.info("MIG712", f"{key}: epoch string {value!r} written as date-time {iso!r}", "/" + key)
        return iso
    return value


def _affordance(
    aff: Any,
    ptr: str,
    endpoints: dict[str, ServiceEndpoint | TopicEndpoint],
    component_of: dict[str, str],
    procedures: dict[str, Any],
    legacy: bool,
) -> Any:
    ep = endpoints.get(ptr)
    if ep is None or not isinstance(aff, dict):
        return aff
    out: dict[str, Any] = {}
    wrote_component = False

    def component() -> None:
        nonlocal wrote_component
        if wrote_component:
            return
        out["rosv:component"] = component_of[ptr]
        proc = procedures.get(ep.name)
        if proc is not None:
            link: dict[str, Any] = {}
            if proc.query:
                link["query"] = proc.query
            if proc.cancel:
                link["cancel"] = proc.cancel
            if proc.mission_id:
                link["missionId"] = "/".join(proc.mission_id)
            if proc.state:
                link["state"] = "/".join(proc.state)
                link["states"] = dict(proc.states)
            if proc.message:
                link["message"] = "/".join(proc.message)
            out["rosv:procedure"] = link
        wrote_component = True

    if isinstance(ep, TopicEndpoint) and legacy:
        if ep.role is Role.SUBSCRIBER:
            out.update({"observable": True, "readOnly": True})
        else:
            out["writeOnly"] = True
    for key, value in aff.items():
        if key == REFERENCE_CLASS_KEY:
            component()
        elif key == "forms" and isinstance(value, list):
            out["forms"] = [_form(f, ep) if isinstance(f, dict) and form_dialect(f) else f for f in value]
        else:
            out[key] = value
    component()
    return out


def _form(form: dict[str, Any], ep: ServiceEndpoint | TopicEndpoint) -> dict[str, Any]:
    out: dict[str, Any] = {"href": "ros:" + ep.ros_name.path}
    for key, value in form.items():
        if key.startswith(("ros:", "rosv:")) or key in ("href", "subprotocol"):
            continue
        if key == "contentType" and value == "application/xml":
            continue  # reference defect: the data is not XML; the default application/json applies
        out[key] = value
    if isinstance(ep, ServiceEndpoint):
        out.setdefault("op", "invokeaction")
        out["rosv:interface"] = "service"
    else:
        if ep.role is Role.PUBLISHER:
            out["op"] = ["writeproperty"]
        else:
            out.setdefault("op", ["readproperty", "observeproperty"])
        out["rosv:interface"] = "topic"
        out["rosv:role"] = ep.role.value
    out["rosv:name"] = ep.ros_name.binding_form()
    out["rosv:type"] = ep.type_name
    if isinstance(ep, TopicEndpoint):
        _qos(out, ep.qos)
    return out


def _qos(out: dict[str, Any], qos: QoS) -> None:
    default = QoS()
    policies = {
        k: getattr(qos, k).value
        for k in ("reliability", "durability", "history")
        if getattr(qos, k) != getattr(default, k)
    }
    if qos.depth != default.depth:
        policies["depth"] = qos.depth
    if policies:
        out["rosv:qos"] = policies
    if qos.latch != default.latch:
        out["rosv:latch"] = qos.latch
    if qos.queue_size != default.queue_size:
        out["rosv:queueSize"] = qos.queue_size
