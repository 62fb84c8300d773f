"""JSON Schema of a ROS message, from its resolved definition, and its meeting with a TD's data schema.

Used to describe payloads (event schemas, the exposed TD, TD data schemas written by migrate or by users) in
the vocabulary TDs use. The schemas are strict, because a payload a ROS message cannot hold must be refused
where it arrives, not fail in a constructor later: every object lists its fields and allows no other
(`additionalProperties: false`); integers and float32 carry their ROS range, fixed arrays their length,
bounded types their bound; time and duration follow the distro (`secs/nsecs` in ROS 1, `sec/nanosec` in ROS
2). A `complete` schema (a value the robot sends: a property, a response) also requires every field; an incomplete
one (a request or a written value) does not, since ROS gives a left-out field its default.

`strictest` lays a TD's data schema over the ROS one: the TD may narrow (ranges, enums, required fields,
patterns, titles) but not widen what the message can carry.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from td2adaptor.model import ArrayKind, FieldType, MessageDef, TypeTable
from td2adaptor.model.primitives import FLOAT32_MAX, int_range

_TIME_TYPES = {"time", "duration", "builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"}
#: a time member's name in the other distro (a TD may be written for either)
TIME_ALIASES = {"sec": "secs", "nanosec": "nsecs", "secs": "sec", "nsecs": "nanosec"}


def time_names(distro: str) -> tuple[str, str]:
    """The seconds and nanoseconds members of a time or duration in `distro`."""
    return ("secs", "nsecs") if distro == "ros1" else ("sec", "nanosec")


def time_schema(distro: str, *, signed: bool = False, complete: bool = False) -> dict[str, Any]:
    """A time (`signed`: a duration) as `distro` defines it: ROS 1's primitives are uint32 pairs (time) and
    int32 pairs (duration); ROS 2's builtin_interfaces has an int32 `sec` and a uint32 `nanosec` in both."""
    secs, nsecs = time_names(distro)
    sec_type = "int32" if signed or distro == "ros2" else "uint32"
    nsec_type = "int32" if signed and distro == "ros1" else "uint32"
    schema: dict[str, Any] = {
        "type": "object",
        "properties": {secs: _scalar(sec_type), nsecs: _scalar(nsec_type)},
        "additionalProperties": False,
    }
    if complete:
        schema["required"] = [secs, nsecs]
    return schema


def _scalar(base: str, distro: str = "ros2") -> dict[str, Any]:
    if base == "bool":
        return {"type": "boolean"}
    rng = int_range(base, distro)
    if rng is not None:
        lo, hi = rng
        return {"type": "integer", "minimum": lo, "maximum": hi}
    if base == "float32":  # float64 takes every number an event may hold (runtime/events.py: finite ones)
        return {"type": "number", "minimum": -FLOAT32_MAX, "maximum": FLOAT32_MAX}
    if base == "float64":
        return {"type": "number"}
    if base in ("string", "wstring"):
        return {"type": "string"}
    return {}


def field_schema(ftype: FieldType, table: TypeTable, *, complete: bool = False) -> dict[str, Any]:
    if ftype.base in _TIME_TYPES and table.distro == "ros1":
        item = time_schema("ros1", signed="uration" in ftype.base, complete=complete)
    elif ftype.is_message:
        found = table.get(ftype.base)
        item = message_schema(found, table, complete=complete) if isinstance(found, MessageDef) else {"type": "object"}
    else:
        item = _scalar(ftype.base, table.distro)
        if ftype.string_bound:
            item["maxLength"] = ftype.string_bound
    if ftype.array is ArrayKind.NONE:
        return item
    arr: dict[str, Any] = {"type": "array", "items": item}
    if ftype.array is ArrayKind.FIXED:
        arr["minItems"] = arr["maxItems"] = ftype.length
    elif ftype.length:
        arr["maxItems"] = ftype.length
    return arr


def message_schema(msg: MessageDef, table: TypeTable, *, complete: bool = False) -> dict[str, Any]:
    """A closed object schema with one property per message field, in definition order (all of them
    required when `complete`)."""
    if msg.name in _TIME_TYPES:
        return time_schema(table.distro, signed="Duration" in msg.name, complete=complete)
    schema: dict[str, Any] = {
        "type": "object",
        "properties": {f.name: field_schema(f.type, table, complete=complete) for f in msg.fields},
        "additionalProperties": False,
    }
    if complete and msg.fields:
        schema["required"] = [f.name for f in msg.fields]
    return schema


_LOWER = ("minimum", "exclusiveMinimum", "minItems", "minLength", "minProperties")
_UPPER = ("maximum", "exclusiveMaximum", "maxItems", "maxLength", "maxProperties")
_KEEP = ("type", "additionalProperties", "properties", "items", "required")


def strictest(ros: Mapping[str, Any], td: Any) -> Any:
    """`ros` (a schema from `message_schema`) narrowed by `td` (a TD data schema, `$`/`@` keywords already
    dropped): members only as the message has them (a TD member named for the other distro's time is
    matched to this one's), bounds the tighter of the two, the TD's enums, patterns, formats and texts, the
    union of the required members. Where the ROS side knows nothing (no `type`), the TD's schema as it is."""
    if not isinstance(td, Mapping):
        return dict(ros)
    if "type" not in ros:
        return dict(td)
    out = dict(ros)
    for key, value in td.items():
        if key in _LOWER and isinstance(value, (int, float)) and not isinstance(value, bool):
            out[key] = max(value, out[key]) if isinstance(out.get(key), (int, float)) else value
        elif key in _UPPER and isinstance(value, (int, float)) and not isinstance(value, bool):
            out[key] = min(value, out[key]) if isinstance(out.get(key), (int, float)) else value
        elif key == "type":
            if ros.get("type") == "number" and value == "integer":
                out["type"] = "integer"
        elif key == "items" and isinstance(value, Mapping) and isinstance(ros.get("items"), Mapping):
            out["items"] = strictest(ros["items"], value)
        elif key == "properties" and isinstance(value, Mapping) and isinstance(ros.get("properties"), Mapping):
            props = dict(ros["properties"])
            for name, sub in value.items():
                own = name if name in props else TIME_ALIASES.get(name)
                if own in props and isinstance(props[own], Mapping):
                    props[own] = strictest(props[own], sub)
            out["properties"] = props
        elif key == "required" and isinstance(value, list):
            names = ros.get("properties") or {}
            wanted = [n if n in names else TIME_ALIASES.get(n, n) for n in value if isinstance(n, str)]
            have = list(ros.get("required") or [])
            out["required"] = have + [n for n in dict.fromkeys(wanted) if n in names and n not in have]
        elif key not in _KEEP:
            out[key] = value
    return out


def default_of(schema: Mapping[str, Any]) -> Any:
    """The value ROS gives a field of this (message) schema when nobody set it: 0, "", false, [] (a fixed
    array: its length in defaults), a message with every field at its default."""
    kind = schema.get("type")
    if kind == "object":
        props = schema.get("properties") or {}
        return {name: default_of(sub) for name, sub in props.items() if isinstance(sub, Mapping)}
    if kind == "array":
        items = schema.get("items")
        count = int(schema.get("minItems") or 0)
        return [default_of(items) if isinstance(items, Mapping) else None for _ in range(count)]
    return {"integer": 0, "number": 0.0, "string": "", "boolean": False}.get(str(kind))


def fill(schema: Mapping[str, Any], value: Any) -> Any:
    """`value` with every field of message schema `schema` it lacks at its ROS default (what a real message
    carries); what it has is kept as it is."""
    if schema.get("type") == "object" and isinstance(value, Mapping):
        props = schema.get("properties") or {}
        out = {str(k): v for k, v in value.items()}
        for name, sub in props.items():
            if isinstance(sub, Mapping):
                out[name] = fill(sub, out[name]) if name in out else default_of(sub)
        return out
    items = schema.get("items")
    if schema.get("type") == "array" and isinstance(value, list) and isinstance(items, Mapping):
        return [fill(items, v) for v in value]
    return value
