"""The TD (or Thing Model) of a layout: affordances in the `rosv` binding, data schemas from the messages.

Schemas come from `model.msgschema` over the ROS 2 type set plus the user's interface folders (TDs use
ROS 2 names and field spellings, `sec`/`nanosec`, whatever the robot runs), the ROS 1 set for a type only
ROS 1 has. A type that resolves nowhere keeps its affordance without a schema (SCF103).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.model import ActionDef, ArrayKind, Constant, MessageDef, ServiceDef, TypeTable
from td2adaptor.model.msgschema import message_schema
from td2adaptor.model.primitives import FLOAT32_MAX
from td2adaptor.rostypes.registry import TypeRegistry
from td2adaptor.scaffold.layout import Layout, Plan

TD_CONTEXT = "https://www.w3.org/2022/wot/td/v1.1"
ROSV_CONTEXT = "https://td2adaptor.dev/ns/rosv/v1"


#: what an event-contract schema adds that a TD's data schema leaves to the contract (which lays the message's
#: own schema over the TD's anyway): closed objects and required fields
_CONTRACT_ONLY = ("additionalProperties", "required")
#: float32's own range, which the contract adds the same way: a TD written for a person leaves it out
_FLOAT32_RANGE = {"minimum": -FLOAT32_MAX, "maximum": FLOAT32_MAX}


def td_style(schema: Any) -> Any:
    """A message schema as a TD writes it: structure, types, ranges and bounds, without `_CONTRACT_ONLY` (and
    without float32's own range)."""
    if isinstance(schema, list):
        return [td_style(s) for s in schema]
    if not isinstance(schema, dict):
        return schema
    out = {}
    float32 = all(schema.get(k) == v for k, v in _FLOAT32_RANGE.items())
    for key, value in schema.items():
        if key in _CONTRACT_ONLY or (float32 and key in _FLOAT32_RANGE):
            continue
        if key == "properties" and isinstance(value, dict):
            out[key] = {name: td_style(sub) for name, sub in value.items()}
        else:
            out[key] = td_style(value)
    return out


def _constant_groups(msg: MessageDef) -> dict[str, list[Constant]]:
    """Field name -> the constants that enumerate its values: same type as the (scalar, primitive) field,
    named `<FIELD NAME IN UPPER CASE>_...`, at least two of them; a constant matching several fields' prefixes
    goes to the longest (`STATUS_CODE_X` to `status_code`, not `status`)."""
    fields = [f for f in msg.fields if not f.type.is_message and f.type.array is ArrayKind.NONE]
    groups: dict[str, list[Constant]] = {}
    for const in msg.constants:
        owners = [f for f in fields if f.type.base == const.type and const.name.startswith(f.name.upper() + "_")]
        if owners:
            groups.setdefault(max(owners, key=lambda f: len(f.name)).name, []).append(const)
    return {name: group for name, group in groups.items() if len(group) >= 2}


#: units a comment may name: symbols (alone, or in brackets: `[m/s]`) and words after "in" (`in Volts`)
_UNIT_SYMBOLS = frozenset(
    {"m", "mm", "cm", "km", "m/s", "m/s^2", "m/s2", "rad", "rad/s", "rad/s^2", "deg", "s", "ms", "us", "ns", "Hz"}
    | {"V", "mV", "A", "mA", "Ah", "W", "Wh", "J", "N", "Nm", "Pa", "kg", "g", "K", "%"}
)
_UNIT_WORDS = {
    "volts": "V",
    "volt": "V",
    "amperes": "A",
    "amps": "A",
    "watts": "W",
    "meters": "m",
    "metres": "m",
    "seconds": "s",
    "radians": "rad",
    "kelvin": "K",
    "celsius": "°C",
    "hertz": "Hz",
    "percent": "%",
    "kilograms": "kg",
    "minutes": "min",
    "hours": "h",
}


def _only_unit(comment: str) -> bool:
    text = comment.strip().rstrip(".")
    return text in _UNIT_SYMBOLS or text.lower() in _UNIT_WORDS


def unit_of(comment: str) -> str | None:
    """The unit a field's comment names where that is plain: the whole comment a unit symbol (`V`), a
    symbol in brackets (`speed [m/s]`), or a unit word after "in" (`Voltage in Volts`, `in degrees Celsius`).
    A comment naming several units (`linear [m/s], angular [rad/s]`) gives none: no one unit is the field's."""
    text = comment.strip().rstrip(".")
    if text in _UNIT_SYMBOLS:
        return text
    if text.lower() in _UNIT_WORDS:
        return _UNIT_WORDS[text.lower()]
    named = [str(inner).strip() for inner in re.findall(r"\[([^\]]+)\]", text)]
    named += [_UNIT_WORDS.get(word.lower(), "") for word in re.findall(r"\bin (?:degrees )?([A-Za-z]+)", text)]
    units = {unit for unit in named if unit in _UNIT_SYMBOLS or unit in _UNIT_WORDS.values()}
    return units.pop() if len(units) == 1 else None


def sentences(texts: Sequence[str]) -> str:
    """Texts joined as sentences: one that does not end a sentence (`the mode`, `How fast,`) gets a full stop."""
    ended = [t if t.endswith((".", "!", "?")) else t.rstrip(",;: ") + "." for t in texts[:-1]]
    return " ".join([*ended, *texts[-1:]])


def annotated(schema: dict[str, Any], msg: MessageDef, table: TypeTable) -> dict[str, Any]:
    """`schema` (the TD style schema of `msg`) with, on each field and in nested messages: the field's .msg
    comment as `description` (and its `unit` when `unit_of` finds one), and `enum` with the constants named
    in the description on a field a group of the message's constants enumerates (`_constant_groups`). A TD
    affair only: the event contract's message schema stays as wide as the type."""
    props = schema.get("properties")
    if not isinstance(props, dict):
        return schema
    groups = _constant_groups(msg)
    for f in msg.fields:
        sub = props.get(f.name)
        if not isinstance(sub, dict):
            continue
        unit = unit_of(f.comment) if f.comment else None
        # a comment that only names the unit (`# V`, `# minutes`) is the unit, not a description
        texts = [f.comment] if f.comment and not _only_unit(f.comment) else []
        if f.name in groups:
            consts = groups[f.name]
            sub["enum"] = [c.value for c in consts]
            named = ", ".join(
                f"{c.name} = {c.value!r}" if isinstance(c.value, str) else f"{c.name} = {c.value}" for c in consts
            )
            texts.append(f"One of the message's constants: {named}.")
        if texts:
            sub["description"] = sentences(texts)
        if unit is not None:
            sub["unit"] = unit
        if f.type.is_message:
            nested = table.get(f.type.base)
            inner = sub.get("items") if f.type.array is not ArrayKind.NONE else sub
            if isinstance(nested, MessageDef) and isinstance(inner, dict):
                annotated(inner, nested, table)
    return schema


class Schemas:
    """JSON Schemas of interface types, from the ROS 2 registry first, then ROS 1 (each built once)."""

    def __init__(
        self,
        interfaces: Sequence[Path],
        diags: Diagnostics,
        recorded: Mapping[str, tuple[str, str]] | None = None,
    ) -> None:
        """`recorded`: the source's own message definitions (a bag's), for the types nothing else defines."""
        self._interfaces = list(interfaces)
        self._recorded = dict(recorded or {})
        self._registries: dict[str, TypeRegistry] = {}
        self._diags = diags
        self._cache: dict[str, list[dict[str, Any]] | None] = {}

    def _registry(self, distro: str) -> TypeRegistry:
        if distro not in self._registries:
            self._registries[distro] = TypeRegistry(
                distro,  # type: ignore[arg-type]
                self._interfaces,
                self._diags,
                self._recorded,
            )
        return self._registries[distro]

    def parts(self, type_name: str) -> list[dict[str, Any]] | None:
        """[message] for a message, [request, response] for a service, [goal, result, feedback] for an
        action; None when no registry resolves it."""
        if type_name not in self._cache:
            self._cache[type_name] = self._resolve(type_name)
        return self._cache[type_name]

    def _resolve(self, type_name: str) -> list[dict[str, Any]] | None:
        for distro in ("ros2", "ros1"):
            table = self._registry(distro).table([type_name])
            if type_name in table.missing:
                continue
            found = table.get(type_name)
            if isinstance(found, MessageDef):
                messages: tuple[MessageDef, ...] = (found,)
            elif isinstance(found, ServiceDef):
                messages = (found.request, found.response)
            elif isinstance(found, ActionDef):
                messages = (found.goal, found.result, found.feedback)
            else:
                continue
            return [annotated(td_style(message_schema(m, table)), m, table) for m in messages]
        return None


def _has_path(schema: dict[str, Any], path: Sequence[str], kind: str) -> bool:
    for part in path:
        schema = schema.get("properties", {}).get(part)
        if not isinstance(schema, dict):
            return False
    return schema.get("type") == kind


def _affordance(p: Plan, schemas: Schemas, diags: Diagnostics) -> dict[str, Any]:
    ep = p.endpoint
    parts = schemas.parts(ep.type)
    if parts is None:
        diags.warning(
            "SCF103",
            f"type {ep.type} of {ep.name} is not known: {p.name} has no data schema",
            hint="give the folder of its interface package with --interfaces",
        )
    form: dict[str, Any] = {"href": p.href}
    out: dict[str, Any] = {"rosv:component": p.component}
    if p.section == "properties":
        reads = ep.role == "publisher"
        form["op"] = ["readproperty", "observeproperty"] if reads else ["writeproperty"]
        form["rosv:role"] = "subscriber" if reads else "publisher"
        if parts is not None:
            out.update(parts[0])
        if reads:
            out.update(observable=True, readOnly=True)
        else:
            out["writeOnly"] = True
    else:
        form["op"] = "invokeaction"
        if p.procedure is not None:
            procedure = dict(p.procedure)
            if parts is not None and _has_path(parts[1], ("state", "header", "id"), "integer"):
                procedure["missionId"] = "state/header/id"
            out["rosv:procedure"] = procedure
        if parts is not None:
            if parts[0].get("properties") or parts[0].get("type") != "object":
                out["input"] = parts[0]  # a request without fields (std_srvs/Trigger) takes no input
            out["output"] = parts[1]
        out.update(safe=p.safe, idempotent=p.safe)
    form["rosv:name"] = p.rosname
    form["rosv:type"] = ep.type
    if ep.kind == "action":
        form["rosv:interface"] = "action"
    if ep.latch:
        form["rosv:latch"] = True
    if ep.qos:
        form["rosv:qos"] = dict(ep.qos)
    out["forms"] = [form]
    return out


def slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "robot"


def write(layout: Layout, schemas: Schemas, diags: Diagnostics, *, title: str | None, label: str) -> dict[str, Any]:
    """The TD, or a Thing Model when the layout is a fleet."""
    if title is None:
        title = layout.namespaces[0] if len(layout.namespaces) == 1 else "Robot"
    doc: dict[str, Any] = {"@context": [TD_CONTEXT, ROSV_CONTEXT]}
    if layout.fleet:
        doc["@type"] = "tm:ThingModel"
        doc["title"] = title
        doc["description"] = (
            f"Thing Model scaffolded by td2adaptor from {label}; instantiate it per robot with robotName "
            f"(the ROS namespace: {', '.join(layout.namespaces)})."
        )
        doc["version"] = {"model": "1.0.0"}
    else:
        doc["@type"] = "Thing"
        doc["id"] = f"urn:dev:wot:td2adaptor:{slug(title)}"
        doc["title"] = title
        doc["description"] = f"Scaffolded by td2adaptor from {label}."
    doc["securityDefinitions"] = {"nosec_sc": {"scheme": "nosec"}}
    doc["security"] = ["nosec_sc"]
    for section in ("properties", "actions"):
        chosen = [p for p in layout.plans if p.section == section]
        if chosen:
            doc[section] = {p.name: _affordance(p, schemas, diags) for p in chosen}
    return doc
