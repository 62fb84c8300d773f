"""How ROS 2 field types look in rclpy Python code: annotations, defaults and conversions.

rosidl's Python messages carry no type information, so the rclpy backend writes stubs and typed
`construct_*` parameters; both come from here. Getter types follow rosidl_generator_py: numeric sequences are
`array.array`, fixed numeric arrays numpy arrays, other arrays lists.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from td2adaptor.generation import textsafe as ts
from td2adaptor.model import ArrayKind, FieldType, MessageField

# `char` in a .msg is uint8 in ROS 2 (rosidl maps it so): an int, and its arrays are numeric arrays
INTS = frozenset({"char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"})
FLOATS = frozenset({"float32", "float64"})
SCALAR = {
    "bool": "bool",
    "byte": "bytes",
    "octet": "bytes",
    "string": "str",
    "wstring": "str",
    **{t: "int" for t in INTS},
    **{t: "float" for t in FLOATS},
}
ZERO = {"bool": "False", "bytes": 'b"\\x00"', "str": '""', "int": "0", "float": "0.0"}


def is_numeric(base: str) -> bool:
    return base in INTS or base in FLOATS


def scalar(ftype: FieldType, msg_name: str) -> str:
    """The Python type of one element: a builtin, or `msg_name` (the local name of the message class)."""
    return msg_name if ftype.is_message else SCALAR[ftype.base]


def getter(ftype: FieldType, msg_name: str) -> str:
    """What reading the field returns (stub attribute annotation)."""
    elem = scalar(ftype, msg_name)
    if ftype.array is ArrayKind.NONE:
        return elem
    if is_numeric(ftype.base):
        return "NDArray[Any]" if ftype.array is ArrayKind.FIXED else f"array.array[{elem}]"
    return f"list[{elem}]"


def init_param(ftype: FieldType, msg_name: str) -> str:
    """What the message constructor accepts for the field (stub `__init__` parameter)."""
    elem = scalar(ftype, msg_name)
    if ftype.array is ArrayKind.NONE:
        return elem
    if is_numeric(ftype.base) and ftype.array is ArrayKind.FIXED:
        return f"Sequence[{elem}] | NDArray[Any]"
    return f"Sequence[{elem}]"


def needs_numpy(ftype: FieldType) -> bool:
    return ftype.array is ArrayKind.FIXED and is_numeric(ftype.base)


def needs_array(ftype: FieldType) -> bool:
    return ftype.array is ArrayKind.SEQUENCE and is_numeric(ftype.base)


def literal(ftype: FieldType, value: Any) -> str | None:
    """A Python literal for a scalar ROS 2 default value, or None when it cannot be one."""
    kind = SCALAR.get(ftype.base)
    if kind == "bool" and isinstance(value, bool):
        return "True" if value else "False"
    if kind == "int" and isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if kind == "float" and isinstance(value, (int, float)) and not isinstance(value, bool):
        number = float(value)
        if math.isnan(number) or math.isinf(number):
            return None
        return repr(number)
    if kind == "str" and isinstance(value, str):
        return ts.py_str(value)
    return None


@dataclass(frozen=True)
class Param:
    """One keyword-only parameter of a generated `construct_*` method or converter, and how it is passed on."""

    name: str  # Python parameter name (the field name, `_`-suffixed if it is a keyword)
    field: str  # the message field it sets
    annotation: str
    default: str
    convert: str  # expression turning the parameter (`{v}`) into the field value
    optional: bool  # None means "leave the ROS default"
    check: str | None = None  # the common.py function `convert` calls with (`{v}`, `{what}`: the field in errors)


def float_check(ftype: FieldType) -> str | None:
    """The common.py function that checks a number field's value (its items: an array's): a float finite, and
    within the float32 range for float32, so that no infinity reaches the robot; an integer within its type's
    range, since Jazzy's rosidl checks nothing by default and would carry 300 in a uint8 as 44."""
    if ftype.is_message or ftype.base not in FLOATS | INTS:
        return None
    return f"check_{ftype.base}" + ("s" if ftype.array is not ArrayKind.NONE else "")


def param(field: MessageField, msg_name: str, converter: str | None, pyname: str) -> Param:
    """The parameter for one field: scalars take their ROS default, messages and arrays default to None."""
    ftype = field.type
    if ftype.array is ArrayKind.NONE and not ftype.is_message:
        kind = SCALAR[ftype.base]
        default = literal(ftype, field.default) if field.default is not None else None
        if default is None:
            default = ZERO[kind]
        check = float_check(ftype)
        convert = f"{check}({{v}}, {{what}})" if check else "{v}"
        return Param(pyname, field.name, kind, default, convert, optional=False, check=check)
    if ftype.array is ArrayKind.NONE:
        return Param(pyname, field.name, f"{msg_name} | Mapping[str, Any] | None", "None", f"{converter}({{v}})", True)
    if ftype.is_message:
        elem = f"{msg_name} | Mapping[str, Any]"
        convert = f"[{converter}(item) for item in {{v}}]"
    else:
        elem = SCALAR[ftype.base]
        check = float_check(ftype)  # other arrays (bool, text): rosidl copies them
        convert = f"{check}({{v}}, {{what}})" if check else "{v}"
        return Param(pyname, field.name, f"Sequence[{elem}] | None", "None", convert, True, check)
    return Param(pyname, field.name, f"Sequence[{elem}] | None", "None", convert, True)
