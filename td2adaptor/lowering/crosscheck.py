"""Cross-check a TD DataSchema against the ROS message it is bound to.

The TD is what clients program against and the message is what the adaptor really converts, so every
difference between the two is a place where data is silently dropped, defaulted or mistyped at run time.
JSON Schema accepts misspelled keys (`"level:"`) and members in the wrong place without complaint, which is
why these mistakes survive schema validation; here they are compared with the message definition instead.

All findings are warnings (one is an info): the TD may be right and the robot's interface different.

Rules, applied recursively (object `properties` ↔ message fields, `items` ↔ array elements):

* schema property that is not a message field → XC601, with a did-you-mean (spelling, case and `_`
  insensitive; when exactly one property and one field are left unmatched in an object they are paired);
* message fields the schema does not describe → XC602, one warning per object listing all of them;
* a member beside `properties` (an unknown keyword) that equals a field name of the message being described
  or of the enclosing one (e.g. `frame_id` inside a `stamp` schema) → XC603, "misplaced field";
* JSON type vs ROS type → XC604: `bool`→boolean; integer types→integer; floats→number (integer accepted);
  strings→string; messages→object; arrays→array (a `uint8`/`byte`/`char` array may also be a base64
  string); ROS 1 `time`/`duration` and ROS 2 `builtin_interfaces` Time/Duration→object. Integer fields
  typed `number` get XC605 instead, since they still accept every valid value;
* time written with the other distribution's member names (`secs`/`nsecs` vs `sec`/`nanosec`) → XC606;
* fixed array `T[N]` with minItems/maxItems other than N, or bounded `T[<=N]` with maxItems above N → XC607;
* `minItems` > 0 on a ROS sequence, which may legitimately be empty → XC608 (info);
* `enum` values that are not among the message's constants of the field's type → XC609. Constants are
  compared only when an `enum` is present and the message defines constants of the same type; if some of
  them carry the field name as a `_`-separated part of their name (`LOCALIZATION_STATE_READY` for `state`)
  only those count, otherwise all of them do;
* `minimum`/`maximum`/`maxLength` that allow values the ROS type cannot hold → XC611.

Schemas that cannot be compared structurally (not an object, `$ref`, `oneOf`/`anyOf`/`allOf`, no `type`,
`properties` or `items`) are skipped without a finding, as are nested types the type table lacks.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Callable, Mapping
from typing import Any, TypeGuard

from td2adaptor.diagnostics import Diagnostics, pointer_join
from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.model import ArrayKind, FieldType, MessageDef, MessageField, TypeTable
from td2adaptor.model.primitives import INT_RANGES as _INT_RANGES

CODES: dict[str, str] = meanings("XC")  # the codes this module reports (see the catalogue)

_FLOATS = {"float32", "float64"}
_STRINGS = {"string", "wstring"}
_BYTES = {"uint8", "byte", "char"}

_ROS2_TIME = {"builtin_interfaces/msg/Time": "time", "builtin_interfaces/msg/Duration": "duration"}
_TIME_DEFS: dict[tuple[str, str], MessageDef] = {}


def _time_def(distro: str, kind: str) -> MessageDef:
    """The members a time/duration has in JSON for `distro` (ROS 1 primitives, ROS 2 builtin messages)."""
    key = (distro, kind)
    if key not in _TIME_DEFS:
        if distro == "ros1":
            base = "uint32" if kind == "time" else "int32"
            fields = (MessageField("secs", FieldType(base)), MessageField("nsecs", FieldType(base)))
            name = kind
        else:
            fields = (MessageField("sec", FieldType("int32")), MessageField("nanosec", FieldType("uint32")))
            name = f"builtin_interfaces/msg/{kind.capitalize()}"
        _TIME_DEFS[key] = MessageDef(name, fields)
    return _TIME_DEFS[key]


# members of a DataSchema (or of the affordance carrying it) that are never message fields
_KEYWORDS = frozenset(
    """@type @context @id title titles description descriptions const default unit oneOf allOf anyOf enum
    readOnly writeOnly format contentEncoding contentMediaType type items minItems maxItems required
    properties propertyName minimum maximum exclusiveMinimum exclusiveMaximum multipleOf minLength maxLength
    pattern $ref $schema $id $comment $defs definitions additionalProperties patternProperties
    additionalItems prefixItems contains uniqueItems minProperties maxProperties not if then else
    dependencies dependentRequired dependentSchemas examples nullable forms uriVariables observable safe
    idempotent synchronous input output subscription data dataResponse cancellation""".split()
)
_UNCOMPARABLE = ("$ref", "oneOf", "anyOf", "allOf")
_MAX_DEPTH = 64
_DISTRO = {"ros1": "ROS 1", "ros2": "ROS 2"}


def crosscheck(
    schema: Any, pointer: str, msg_name: str, types: TypeTable, diags: Diagnostics, *, label: str = ""
) -> None:
    """Compare the DataSchema `schema` (at `pointer` in the TD) with message `msg_name` from `types`.

    `label` (e.g. "input of action `gotoRun`") prefixes every message. Nothing is reported when the message
    is not in the table: unresolved types are reported where types are resolved.
    """
    root = types.get(msg_name)
    if not isinstance(root, MessageDef):
        return
    _Checker(root.name, types, diags, label).scalar(schema, pointer, FieldType(root.name, True), "", None, 0)


class _Checker:
    def __init__(self, root: str, types: TypeTable, diags: Diagnostics, label: str) -> None:
        self.root = root
        self.types = types
        self.diags = diags
        self.prefix = f"{label}: " if label else ""

    # -- reporting --------------------------------------------------------------------------------------

    def where(self, path: str) -> str:
        return f"`{path}` of `{self.root}`" if path else f"`{self.root}`"

    def at(self, path: str, preposition: str = "at") -> str:
        """Where in the root message `path` is; empty at the root, which the message names anyway."""
        return f" {preposition} {self.where(path)}" if path else ""

    def warn(self, code: str, message: str, pointer: str, hint: str | None = None) -> None:
        self.diags.warning(code, self.prefix + message, pointer, hint)

    # -- walking ----------------------------------------------------------------------------------------

    def field(self, schema: Any, ptr: str, ftype: FieldType, path: str, owner: MessageDef | None, depth: int) -> None:
        """Compare `schema` with a field of type `ftype` (array or not)."""
        if not _comparable(schema) or depth > _MAX_DEPTH:
            return
        if ftype.array is ArrayKind.NONE:
            self.scalar(schema, ptr, ftype, path, owner, depth)
            return
        element = FieldType(ftype.base, ftype.is_message, string_bound=ftype.string_bound)
        jtypes = _json_types(schema)
        if jtypes and "array" not in jtypes:
            if "string" in jtypes and ftype.base in _BYTES:
                return  # byte arrays travel as base64 strings
            self.mismatch(ptr, path, ftype, jtypes, "array")
            if "object" in jtypes and ftype.is_message and isinstance(schema.get("properties"), dict):
                # the schema describes one element instead of the array: still compare the element
                self.scalar(schema, ptr, element, path + "[]", owner, depth + 1)
            return
        self.array_bounds(schema, ptr, ftype, path)
        items = schema.get("items")
        if isinstance(items, dict):
            self.field(items, pointer_join(ptr, "items"), element, path + "[]", owner, depth + 1)

    def scalar(self, schema: Any, ptr: str, ftype: FieldType, path: str, owner: MessageDef | None, depth: int) -> None:
        """Compare `schema` with one (non-array) value of type `ftype`."""
        if not _comparable(schema) or depth > _MAX_DEPTH:
            return
        jtypes = _json_types(schema)
        time_kind = _time_kind(ftype)
        if time_kind is not None:
            self.time(schema, ptr, ftype, time_kind, path, jtypes, depth)
        elif ftype.is_message:
            if jtypes and "object" not in jtypes:
                self.mismatch(ptr, path, ftype, jtypes, "object")
                items = schema.get("items")
                if "array" in jtypes and isinstance(items, dict):
                    self.scalar(items, pointer_join(ptr, "items"), ftype, path, owner, depth + 1)
                return
            msg = self.types.get(ftype.base)
            if isinstance(msg, MessageDef):
                self.message(schema, ptr, msg, path, depth)
        else:
            self.primitive(schema, ptr, ftype, path, owner, jtypes)

    def message(self, schema: Mapping[str, Any], ptr: str, msg: MessageDef, path: str, depth: int) -> None:
        """Compare an object schema member by member with the fields of `msg`."""
        fields = {f.name: f for f in msg.fields}
        props = schema.get("properties")
        if not isinstance(props, dict):
            props = {}
        # fields written beside `properties`: in this schema, or one level down in a member's schema
        misplaced: dict[str, tuple[str, Any]] = {}
        for key, value in schema.items():
            if key in fields and key not in _KEYWORDS and key not in props:
                misplaced.setdefault(key, (pointer_join(ptr, key), value))
        for name, sub in props.items():
            if isinstance(sub, dict):
                for key, value in sub.items():
                    if key in fields and key not in _KEYWORDS and key not in props and key != name:
                        misplaced.setdefault(key, (pointer_join(ptr, "properties", name, key), value))
        if not props and not misplaced:
            return  # e.g. {"type": "object"}: nothing to compare member by member
        unknown = [n for n in props if n not in fields]
        missing = [n for n in fields if n not in props and n not in misplaced]
        suggestions = _suggest(unknown, missing, lambda u, f: _fits(props[u], fields[f].type))
        for name in unknown:
            guess = suggestions.get(name)
            members = ", ".join(fields) or "no fields"
            self.warn(
                "XC601",
                f"schema property `{name}`{self.at(path)} is not a field of `{msg.name}` ({members})",
                pointer_join(ptr, "properties", name),
                f"did you mean `{guess}`?" if guess else "remove it, or bind the affordance to the right type",
            )
        for name, (where, value) in misplaced.items():
            self.warn(
                "XC603",
                f"misplaced field: `{_join(path, name)}` of `{self.root}` is written beside `properties`, "
                "so JSON Schema ignores it",
                where,
                f"move `{name}` into the `properties` of the schema for {self.where(path)}",
            )
            self.field(value, where, fields[name].type, _join(path, name), msg, depth + 1)
        remaining = [n for n in missing if n not in suggestions.values()]
        if remaining and props:
            listed = ", ".join(f"`{n}` ({fields[n].type})" for n in remaining)
            self.warn(
                "XC602",
                f"schema{self.at(path, 'for')} does not describe message field"
                f"{'s' if len(remaining) > 1 else ''} {listed} of `{msg.name}`",
                pointer_join(ptr, "properties"),
                "describe every field, so clients know what they receive and what they must send",
            )
        for name, sub in props.items():
            if name in fields:
                self.field(
                    sub,
                    pointer_join(ptr, "properties", name),
                    fields[name].type,
                    _join(path, name),
                    msg,
                    depth + 1,
                )

    def time(self, schema: Any, ptr: str, ftype: FieldType, kind: str, path: str, jtypes: set[str], depth: int) -> None:
        if jtypes and "object" not in jtypes:
            self.mismatch(ptr, path, ftype, jtypes, "object")
            return
        distro = "ros1" if self.types.distro == "ros1" else "ros2"
        other = "ros2" if distro == "ros1" else "ros1"
        own_def, other_def = _time_def(distro, kind), _time_def(other, kind)
        props = schema.get("properties")
        names = set(props) if isinstance(props, dict) else set()
        own = {f.name for f in own_def.fields}
        theirs = {f.name for f in other_def.fields}
        if names and names <= theirs and not names & own:
            spelled = "/".join(f.name for f in other_def.fields)
            wanted = "/".join(f.name for f in own_def.fields)
            self.warn(
                "XC606",
                f"{self.where(path)} is a {_DISTRO[distro]} {kind}, written in JSON as {wanted}, "
                f"but the schema uses the {_DISTRO[other]} names {spelled}",
                pointer_join(ptr, "properties"),
                f"use {wanted} for {distro}",
            )
            self.message(schema, ptr, other_def, path, depth)
            return
        self.message(schema, ptr, own_def, path, depth)

    def primitive(
        self,
        schema: Mapping[str, Any],
        ptr: str,
        ftype: FieldType,
        path: str,
        owner: MessageDef | None,
        jtypes: set[str],
    ) -> None:
        base = ftype.base
        expected = _json_type_of(base)
        if expected is None:
            return
        if jtypes:
            if expected == "integer" and "integer" not in jtypes and "number" in jtypes:
                self.warn(
                    "XC605",
                    f"{self.where(path)} is {ftype} but the schema declares `number`, which admits fractions",
                    pointer_join(ptr, "type"),
                    'use "type": "integer"',
                )
            elif not _accepts(expected, jtypes):
                self.mismatch(ptr, path, ftype, jtypes, expected)
                return
        self.ranges(schema, ptr, ftype, path, expected)
        if owner is not None:
            self.enum_constants(schema, ptr, ftype, path, owner)

    # -- individual rules -------------------------------------------------------------------------------

    def mismatch(self, ptr: str, path: str, ftype: FieldType, jtypes: set[str], expected: str) -> None:
        declared = " or ".join(f"`{t}`" for t in sorted(jtypes))
        self.warn(
            "XC604",
            f"{self.where(path)} is {ftype} but the schema declares type {declared}",
            pointer_join(ptr, "type"),
            f'use "type": "{expected}"',
        )

    def array_bounds(self, schema: Mapping[str, Any], ptr: str, ftype: FieldType, path: str) -> None:
        lo, hi = _int_or_none(schema.get("minItems")), _int_or_none(schema.get("maxItems"))
        if ftype.array is ArrayKind.FIXED:
            n = ftype.length
            if (lo is not None and lo != n) or (hi is not None and hi != n):
                self.warn(
                    "XC607",
                    f"{self.where(path)} is {ftype}, always exactly {n} items, but the schema allows "
                    f"{_range_text(lo, hi)}",
                    ptr,
                    f'use "minItems": {n}, "maxItems": {n}',
                )
            return
        if ftype.length and hi is not None and hi > ftype.length:
            self.warn(
                "XC607",
                f"{self.where(path)} is {ftype}, at most {ftype.length} items, but the schema allows up to {hi}",
                pointer_join(ptr, "maxItems"),
                f'use "maxItems": {ftype.length} or less',
            )
        if lo is not None and lo > 0:
            self.diags.info(
                "XC608",
                f"{self.prefix}{self.where(path)} is a ROS sequence ({ftype}), which may be empty, "
                f"but the schema requires at least {lo} item{'s' if lo > 1 else ''}",
                pointer_join(ptr, "minItems"),
                "drop minItems unless the robot really never sends or accepts an empty sequence",
            )

    def ranges(self, schema: Mapping[str, Any], ptr: str, ftype: FieldType, path: str, expected: str) -> None:
        if expected == "integer":
            lo, hi = _integer_range(ftype.base, self.types.distro)
            for key in ("minimum", "maximum"):
                value = schema.get(key)
                if _is_number(value) and (value < lo if key == "minimum" else value > hi):
                    self.warn(
                        "XC611",
                        f"{self.where(path)} is {ftype} ({lo}..{hi}) but the schema has {key} {value}",
                        pointer_join(ptr, key),
                        f"keep {key} within {lo}..{hi}",
                    )
        elif expected == "string" and ftype.string_bound:
            value = schema.get("maxLength")
            if _is_number(value) and value > ftype.string_bound:
                self.warn(
                    "XC611",
                    f"{self.where(path)} is {ftype} but the schema has maxLength {value}",
                    pointer_join(ptr, "maxLength"),
                    f'use "maxLength": {ftype.string_bound} or less',
                )

    def enum_constants(
        self, schema: Mapping[str, Any], ptr: str, ftype: FieldType, path: str, owner: MessageDef
    ) -> None:
        enum = schema.get("enum")
        if not isinstance(enum, list) or not enum:
            return
        same_type = [c for c in owner.constants if c.type == ftype.base]
        if not same_type:
            return
        token = f"_{path.rsplit('.', 1)[-1].removesuffix('[]').upper()}_"
        named = [c for c in same_type if token in f"_{c.name}_"]
        constants = named or same_type
        values = [c.value for c in constants]
        bad = [v for v in enum if not any(type(v) is type(c) and v == c for c in values)]
        if bad:
            self.warn(
                "XC609",
                f"enum value{'s' if len(bad) > 1 else ''} {', '.join(repr(v) for v in bad)} "
                f"of {self.where(path)} {'are' if len(bad) > 1 else 'is'} not among the constants "
                f"of `{owner.name}` ({', '.join(f'{c.name}={c.value!r}' for c in constants)})",
                pointer_join(ptr, "enum"),
                "use the constants the message defines",
            )


# -- helpers --------------------------------------------------------------------------------------------


def _comparable(schema: Any) -> bool:
    return isinstance(schema, dict) and not any(k in schema for k in _UNCOMPARABLE)


def _json_types(schema: Mapping[str, Any]) -> set[str]:
    """Declared JSON types; when `type` is absent, `properties` implies object and `items` array."""
    declared = schema.get("type")
    if isinstance(declared, str):
        return {declared}
    if isinstance(declared, list):
        return {t for t in declared if isinstance(t, str)}
    if isinstance(schema.get("properties"), dict):
        return {"object"}
    if isinstance(schema.get("items"), dict):
        return {"array"}
    return set()


def _json_type_of(base: str) -> str | None:
    if base == "bool":
        return "boolean"
    if base in _INT_RANGES or base == "byte":
        return "integer"
    if base in _FLOATS:
        return "number"
    if base in _STRINGS:
        return "string"
    return None


def _fits(schema: Any, ftype: FieldType) -> bool:
    """Whether `schema`'s declared JSON type (if any) could describe a field of type `ftype`."""
    jtypes = _json_types(schema) if isinstance(schema, dict) else set()
    if not jtypes:
        return True
    if ftype.array is not ArrayKind.NONE:
        expected: str | None = "array"
    elif ftype.is_message or _time_kind(ftype) is not None:
        expected = "object"
    else:
        expected = _json_type_of(ftype.base)
    return expected is None or _accepts(expected, jtypes) or (expected == "integer" and "number" in jtypes)


def _accepts(expected: str, jtypes: set[str]) -> bool:
    if expected in jtypes:
        return True
    return expected == "number" and "integer" in jtypes


def _integer_range(base: str, distro: str) -> tuple[int, int]:
    if base == "byte":  # ROS 1: deprecated alias of int8; ROS 2: octet
        return _INT_RANGES["int8"] if distro == "ros1" else _INT_RANGES["uint8"]
    return _INT_RANGES[base]


def _time_kind(ftype: FieldType) -> str | None:
    if not ftype.is_message and ftype.base in ("time", "duration"):
        return ftype.base
    return _ROS2_TIME.get(ftype.base) if ftype.is_message else None


def _suggest(unknown: list[str], missing: list[str], fits: Callable[[str, str], bool]) -> dict[str, str]:
    """Unknown schema property → the unmatched field it most likely means.

    Similar spelling always counts; a lone leftover pair (`title` vs `name`) only when the property's schema
    could describe the field, so `_format` is not offered as `last_message`.
    """
    out: dict[str, str] = {}
    by_norm = {_norm(m): m for m in missing}
    for name in unknown:
        norm = _norm(name)
        if norm in by_norm:
            out[name] = by_norm[norm]
            continue
        close = difflib.get_close_matches(norm, list(by_norm), n=1, cutoff=0.75)
        if close:
            out[name] = by_norm[close[0]]
    left_unknown = [u for u in unknown if u not in out]
    left_missing = [m for m in missing if m not in out.values()]
    if len(left_unknown) == 1 and len(left_missing) == 1 and fits(left_unknown[0], left_missing[0]):
        out[left_unknown[0]] = left_missing[0]  # the only leftovers on both sides: a rename
    return out


def _norm(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _int_or_none(value: Any) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _is_number(value: Any) -> TypeGuard[int | float]:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _range_text(lo: int | None, hi: int | None) -> str:
    if lo is not None and hi is not None:
        return f"{lo}..{hi} items"
    if lo is not None:
        return f"at least {lo} items"
    return f"at most {hi} items"
