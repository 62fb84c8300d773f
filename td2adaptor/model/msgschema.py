"""JSON Schema of a ROS message, from its resolved definition.

Used to describe payloads (event schemas, TD data schemas written by migrate or by users) in the same
vocabulary TDs use. Integers carry their ROS range, fixed arrays their length, bounded types their bound;
time and duration follow the distro (`secs/nsecs` in ROS 1, `sec/nanosec` in ROS 2).
"""

from __future__ import annotations

from typing import Any

from td2adaptor.model import ArrayKind, FieldType, MessageDef, TypeTable
from td2adaptor.rostypes.primitives import int_range

_TIME_TYPES = {"time", "duration", "builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"}


def time_schema(distro: str, *, signed: bool = False) -> dict[str, Any]:
    secs, nsecs = ("secs", "nsecs") if distro == "ros1" else ("sec", "nanosec")
    sec_type = "int32" if signed or distro == "ros2" else "uint32"
    return {
        "type": "object",
        "properties": {secs: _scalar(sec_type), nsecs: _scalar("int32" if signed else "uint32")},
    }


def _scalar(base: str, distro: str = "ros2") -> dict[str, Any]:
    if base == "bool":
        return {"type": "boolean"}
    rng = int_range(base, distro)
    if rng is not None:
        lo, hi = rng
        return {"type": "integer", "minimum": lo, "maximum": hi}
    if base in ("float32", "float64"):
        return {"type": "number"}
    if base in ("string", "wstring"):
        return {"type": "string"}
    return {}


def field_schema(ftype: FieldType, table: TypeTable) -> dict[str, Any]:
    if ftype.base in _TIME_TYPES and table.distro == "ros1":
        item = time_schema("ros1", signed="uration" in ftype.base)
    elif ftype.is_message:
        found = table.get(ftype.base)
        item = message_schema(found, table) if isinstance(found, MessageDef) else {"type": "object"}
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


def message_schema(msg: MessageDef, table: TypeTable) -> dict[str, Any]:
    """An object schema with one property per message field, in definition order."""
    if msg.name in _TIME_TYPES:
        return time_schema(table.distro, signed="Duration" in msg.name)
    return {"type": "object", "properties": {f.name: field_schema(f.type, table) for f in msg.fields}}
