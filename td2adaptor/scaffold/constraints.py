"""`--merge` and a person's constraints: which hand-written limits survive a fresh scaffold, and why not.

A person narrows what a message may carry (`minimum`, `maximum`, `maxItems`, `pattern`, ...) and the edge
node enforces those limits, so a merge keeps each one the ROS type does not contradict. The type contradicts
a constraint that applies to another JSON type than the field's, a bound looser than the type's own (a
minimum below a uint8's 0, a `maxItems` above the array's bound) and a bound that leaves no value the type
allows. Every constraint that ends up other than the scaffold wrote it is recorded as a `Change`, so the
merge can say what it kept and what it dropped.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from td2adaptor.model.primitives import INT_RANGES

_NUMBERS = ("integer", "number")
#: constraint member -> the JSON types it applies to (None: any)
APPLIES: dict[str, tuple[str, ...] | None] = {
    "minimum": _NUMBERS,
    "exclusiveMinimum": _NUMBERS,
    "maximum": _NUMBERS,
    "exclusiveMaximum": _NUMBERS,
    "multipleOf": _NUMBERS,
    "minItems": ("array",),
    "maxItems": ("array",),
    "uniqueItems": ("array",),
    "minLength": ("string",),
    "maxLength": ("string",),
    "pattern": ("string",),
    "format": ("string",),
    "contentEncoding": ("string",),
    "contentMediaType": ("string",),
    "const": None,
    "required": ("object",),
}
CONSTRAINTS = frozenset(APPLIES)


@dataclass(frozen=True)
class Change:
    """A hand-written constraint that differs from the scaffold's: kept (`reason` None) or dropped."""

    pointer: str
    value: Any
    reason: str | None = None


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def type_text(schema: Mapping[str, Any]) -> str:
    """How a reason names the field's ROS type: `uint8 (0..255)` for an integer, else the JSON type."""
    kind = schema.get("type")
    lo, hi = schema.get("minimum"), schema.get("maximum")
    if kind == "integer" and _number(lo) and _number(hi):
        names = [name for name, rng in INT_RANGES.items() if rng == (lo, hi) and name != "char"]
        return f"{names[0]} ({lo}..{hi})" if names else f"an integer in {lo}..{hi}"
    if kind == "array":
        fixed = schema.get("minItems")
        if _count(fixed) and fixed == schema.get("maxItems"):
            return f"an array of exactly {fixed} items"
        return f"an array of at most {schema['maxItems']} items" if _count(schema.get("maxItems")) else "an array"
    if kind == "string" and _count(schema.get("maxLength")):
        return f"a string of at most {schema['maxLength']} characters"
    return {"number": "a number", "string": "a string", "boolean": "a boolean", "object": "a message"}.get(
        str(kind), "untyped"
    )


def _numeric(key: str, value: Any, ros: Mapping[str, Any]) -> str | None:
    """Why the ROS range contradicts a numeric bound (None: it does not)."""
    if not _number(value):
        return "not a number"
    if key == "multipleOf":
        return None if value > 0 else "not above 0"
    lo, hi = ros.get("minimum"), ros.get("maximum")
    lower = key in ("minimum", "exclusiveMinimum")
    if lower and _number(lo) and value < lo:
        return f"below the minimum of {type_text(ros)}"
    if not lower and _number(hi) and value > hi:
        return f"above the maximum of {type_text(ros)}"
    empty = (
        (key == "minimum" and _number(hi) and value > hi)
        or (key == "exclusiveMinimum" and _number(hi) and value >= hi)
        or (key == "maximum" and _number(lo) and value < lo)
        or (key == "exclusiveMaximum" and _number(lo) and value <= lo)
    )
    return f"leaves no value of {type_text(ros)}" if empty else None


def _counted(key: str, value: Any, ros: Mapping[str, Any]) -> str | None:
    """Why the ROS type's length bounds contradict a hand-written one (None: they do not)."""
    if not _count(value):
        return "not a count"
    noun = "Items" if key.endswith("Items") else "Length"
    least, most = ros.get("min" + noun, 0), ros.get("max" + noun)
    if key.startswith("max"):
        if _count(most) and value > most:
            return f"more than {type_text(ros)} holds"
        return f"fewer than {type_text(ros)} holds" if _count(least) and value < least else None
    if _count(least) and value < least:
        return f"fewer than {type_text(ros)} holds"
    return f"more than {type_text(ros)} holds" if _count(most) and value > most else None


def _const(value: Any, ros: Mapping[str, Any]) -> str | None:
    from jsonschema import Draft7Validator  # type: ignore[import-untyped, unused-ignore]

    valid: bool = Draft7Validator(dict(ros)).is_valid(value)
    return None if valid else f"not a value of {type_text(ros)}"


def contradiction(key: str, value: Any, ros: Mapping[str, Any]) -> str | None:
    """Why the ROS type's schema `ros` contradicts hand-written constraint `key: value` (None: it does not)."""
    kinds = APPLIES[key]
    kind = ros.get("type")
    if kinds is not None and kind is not None and kind not in kinds:
        return f"the field is {type_text(ros)}"
    if key in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum", "multipleOf"):
        return _numeric(key, value, ros)
    if key in ("minItems", "maxItems", "minLength", "maxLength"):
        return _counted(key, value, ros)
    if key == "const":
        return _const(value, ros)
    if key == "uniqueItems":
        return None if isinstance(value, bool) else "not true or false"
    if key == "required":
        return None if isinstance(value, list) else "not a list of field names"
    return None if isinstance(value, str) else "not a string"


def lay_over(
    old: Mapping[str, Any], ros: Mapping[str, Any], out: dict[str, Any], where: str, changes: list[Change]
) -> None:
    """Put into `out` (the merged schema, built from `ros`) the constraints of `old` that `ros` does not
    contradict; record in `changes` each kept one that differs from the scaffold's and each dropped one."""
    if old.get("type") == "integer" and ros.get("type") == "number":  # a float field a person keeps whole
        out["type"] = "integer"
        changes.append(Change(f"{where}/type", "integer"))
    fields = ros.get("properties")
    for key, value in old.items():
        if key not in CONSTRAINTS or ros.get(key) == value:
            continue
        if key == "required" and isinstance(value, list) and isinstance(fields, Mapping):
            gone = [n for n in value if n not in fields]
            for name in gone:
                changes.append(Change(f"{where}/required", name, f"the message has no field {name}"))
            value = [n for n in value if n in fields]
            if not value:
                continue
        reason = contradiction(key, value, ros)
        changes.append(Change(f"{where}/{key}", value, reason))
        if reason is None:
            out[key] = value


def gone(old: Mapping[str, Any], where: str, changes: list[Change]) -> None:
    """Record the constraints inside a field the message no longer has (they go with it)."""
    for key, value in old.items():
        if key in CONSTRAINTS:
            changes.append(Change(f"{where}/{key}", value, "the message has no such field any more"))
    for key in ("items",):
        sub = old.get(key)
        if isinstance(sub, Mapping):
            gone(sub, f"{where}/{key}", changes)
    props = old.get("properties")
    if isinstance(props, Mapping):
        for name, sub in props.items():
            if isinstance(sub, Mapping):
                gone(sub, f"{where}/properties/{name}", changes)
