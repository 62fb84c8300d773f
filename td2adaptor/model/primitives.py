"""ROS primitive types: value ranges and families, in one place for the parser, cross-check and schemas."""

from __future__ import annotations

INT_RANGES: dict[str, tuple[int, int]] = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
    "char": (0, 2**8 - 1),
}
#: the integer types a mission id may have (char and byte read as characters and bytes, not numbers)
INTEGERS = frozenset({"int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"})
FLOATS = frozenset({"float32", "float64"})
#: the largest finite float32 (C's FLT_MAX, (2 - 2**-23) * 2**127): a float32 field's range is +-this; a double
#: beyond it would become infinity on the way into the message
FLOAT32_MAX = 3.4028234663852886e38
STRINGS = frozenset({"string", "wstring"})


def int_range(base: str, distro: str) -> tuple[int, int] | None:
    """Range of an integer primitive; `byte` is signed in ROS 1 (int8) and unsigned in ROS 2 (octet)."""
    if base == "byte":
        return INT_RANGES["int8"] if distro == "ros1" else INT_RANGES["uint8"]
    return INT_RANGES.get(base)
