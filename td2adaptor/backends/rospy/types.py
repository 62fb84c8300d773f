"""ROS 1 types as Python (genpy) sees them: class locations, annotations, defaults and conversions.

Shared by the rospy backend's component view and its type stubs, so the stubs describe exactly the values
the generated code builds.
"""

from __future__ import annotations

import keyword
from dataclasses import dataclass

from td2adaptor.backends._python.text import call_lines
from td2adaptor.generation.textsafe import py_str
from td2adaptor.model import ArrayKind, FieldType, MessageField

_INTS = frozenset("byte char int8 uint8 int16 uint16 int32 uint32 int64 uint64".split())
_FLOATS = frozenset(("float32", "float64"))
_BYTES = frozenset(("uint8", "char", "byte"))


def py_scalar(base: str) -> str:
    """The Python type of a ROS 1 primitive (`genpy.Time` for time)."""
    if base == "bool":
        return "bool"
    if base in _INTS:
        return "int"
    if base in _FLOATS:
        return "float"
    if base == "string":
        return "str"
    if base == "time":
        return "genpy.Time"
    if base == "duration":
        return "genpy.Duration"
    raise ValueError(f"not a ROS 1 primitive: {base}")


def scalar_default(base: str) -> str:
    """ROS 1 has no declared defaults: every field starts at its zero value, as genpy does."""
    if base == "bool":
        return "False"
    if base in _INTS:
        return "0"
    if base in _FLOATS:
        return "0.0"
    if base == "string":
        return '""'
    raise ValueError(f"no literal default for {base}")


def class_location(name: str) -> tuple[str, str]:
    """(module, class) of a canonical type: `pkg/msg/N` → (pkg.msg, N); `pkg/srv/N_Request` → (pkg.srv, NRequest);
    ROS 1 actions are messages (genaction): `pkg/action/N_Goal` → (pkg.msg, NGoal), `pkg/action/N` → (pkg.msg,
    NAction)."""
    package, kind, short = name.split("/")
    if kind == "srv":
        for suffix in ("_Request", "_Response"):
            if short.endswith(suffix):
                short = short[: -len(suffix)] + suffix[1:]
    if kind == "action":
        return f"{package}.msg", short.replace("_", "") if "_" in short else short + "Action"
    return f"{package}.{kind}", short


def is_byte_array(ftype: FieldType) -> bool:
    """uint8[] and char[] are `bytes` in genpy under Python 3."""
    return ftype.array is not ArrayKind.NONE and not ftype.is_message and ftype.base in _BYTES


def field_problem(field: MessageField) -> str | None:
    """Why a field cannot become a Python attribute and keyword parameter (None when it can)."""
    if not field.name.isidentifier() or not field.name.isascii() or keyword.iskeyword(field.name):
        return f"field {field.name!r} is not usable as a Python name"
    if field.name.startswith("_"):
        return f"field {field.name!r} starts with '_'"
    return None


@dataclass(frozen=True)
class FieldView:
    """How one field appears as a keyword parameter of a construct_*_Msg method."""

    field: str  # the message field
    param: str  # the parameter (the field name unless that would shadow something)
    annotation: str
    default: str
    value: str  # expression turning the parameter into the field's value
    check: tuple[str, str] | None = None  # `value` is this common.py check called with (value, the field's name)

    @property
    def kwarg_lines(self) -> list[str]:
        """`field=value,` in a call indented by 12, as ruff's formatter lays it out (parenthesised when long, a
        check's arguments split)."""
        if self.check is not None:
            return call_lines(f"{self.field}=", self.check[0], (self.check[1], py_str(self.field)), ",", 12)
        line = f"{self.field}={self.value},"
        if 12 + len(line) <= 120:
            return [line]
        return [f"{self.field}=(", f"    {self.value}", "),"]


def float_check(base: str, array: bool) -> str | None:
    """The common.py function that checks a float field's value (an array's items): finite, and within the
    float32 range for float32, so that no infinity reaches the robot."""
    if base not in _FLOATS:
        return None
    return f"check_{base}" + ("s" if array else "")


def field_view(field: MessageField, param: str, local: dict[str, str]) -> FieldView:
    """`local` maps canonical message names to the class names the generated module uses."""
    ftype = field.type
    if ftype.is_message:
        cls = local[ftype.base]
        if ftype.array is ArrayKind.NONE:
            value = f"{param} if isinstance({param}, {cls}) else to_msg({cls}, {param})"  # no call when given a message
            return FieldView(field.name, param, f"{cls} | Mapping[str, Any] | None", "None", value)
        if ftype.array is ArrayKind.FIXED:
            value = f"to_msgs({cls}, {param}) if {param} is not None else [{cls}() for _ in range({ftype.length})]"
        else:
            value = f"to_msgs({cls}, {param})"
        return FieldView(field.name, param, f"Sequence[{cls} | Mapping[str, Any]] | None", "None", value)
    if ftype.base in ("time", "duration"):
        helper = "to_time" if ftype.base == "time" else "to_duration"
        scalar = py_scalar(ftype.base)
        if ftype.array is ArrayKind.NONE:
            return FieldView(field.name, param, f"{scalar} | Mapping[str, int] | None", "None", f"{helper}({param})")
        fill = f"[{scalar}() for _ in range({ftype.length})]" if ftype.array is ArrayKind.FIXED else "[]"
        value = f"[{helper}(item) for item in {param}] if {param} is not None else {fill}"
        return FieldView(field.name, param, f"Sequence[{scalar} | Mapping[str, int]] | None", "None", value)
    if is_byte_array(ftype):
        if ftype.array is ArrayKind.FIXED:
            value = f"bytes({param}) if {param} is not None else bytes({ftype.length})"
            return FieldView(field.name, param, "bytes | Sequence[int] | None", "None", value)
        return FieldView(field.name, param, "bytes | Sequence[int]", 'b""', f"bytes({param})")
    scalar = py_scalar(ftype.base)
    check = float_check(ftype.base, ftype.array is not ArrayKind.NONE)
    if ftype.array is ArrayKind.NONE:
        value = param if check is None else f"{check}({param}, {py_str(field.name)})"
        return FieldView(field.name, param, scalar, scalar_default(ftype.base), value, _with(check, param))
    length = ftype.length if ftype.array is ArrayKind.FIXED else 0
    value = f"to_list({param}, {length}, {scalar_default(ftype.base)})"
    checked = value if check is None else f"{check}({value}, {py_str(field.name)})"
    return FieldView(field.name, param, f"Sequence[{scalar}] | None", "None", checked, _with(check, value))


def _with(check: str | None, value: str) -> tuple[str, str] | None:
    return None if check is None else (check, value)


def stub_annotation(ftype: FieldType, ref: dict[str, str]) -> str:
    """The attribute type in a message stub; `ref` maps canonical message names to how the stub refers to them.

    Message arrays are lists (genpy builds them so); primitive arrays may be lists or tuples (deserialised).
    """
    if ftype.is_message:
        inner = ref[ftype.base]
        return inner if ftype.array is ArrayKind.NONE else f"list[{inner}]"
    if is_byte_array(ftype):
        return "bytes"
    scalar = py_scalar(ftype.base)
    return scalar if ftype.array is ArrayKind.NONE else f"Sequence[{scalar}]"


def constant_annotation(ros_type: str) -> str:
    return "str" if ros_type == "string" else py_scalar(ros_type)
