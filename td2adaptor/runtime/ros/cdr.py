"""Serialized ROS 2 messages (classic CDR, as rclpy's raw subscriptions give them) straight to JSON-ready values.

Why: relaying a sensor stream at full rate (`property_mode: message`) spent most of its time making rosidl
Python message objects (each nested message's `__init__` and property setters run in Python) only to turn them
into dicts again. A decoder compiled once per message type reads the bytes into exactly the values
`genport.to_plain` gives for the deserialized message (so the event is the same, byte for byte).

A decoder is Python source generated from the message class's rosidl definition (`SLOT_TYPES`) and compiled
once, as dataclasses and namedtuple do. Consecutive fixed-size fields, across nested messages, are read with one
`struct.Struct`; where their alignment is only known at run time (after a string or a sequence) there is one
Struct per offset modulo 8. Nothing but integers, local names and repr() of rosidl field names (identifiers)
reaches the source. Read: little-endian classic CDR (encapsulation 0x0001, what rmw_fastrtps and rmw_cyclonedds
write on x86 and ARM); anything else raises `CdrError` and the caller deserializes the usual way.
"""

from __future__ import annotations

import importlib
import struct
from collections.abc import Callable
from typing import Any

__all__ = ["CdrError", "decoder", "message_class", "plain_reader"]


class CdrError(ValueError):
    """The bytes are not little-endian classic CDR of the decoder's message type (or are cut short)."""


#: rosidl basic type → (struct format character, size = alignment, kind of value)
_BASIC: dict[str, tuple[str, int, str]] = {
    "boolean": ("?", 1, "bool"),
    "octet": ("B", 1, "octet"),
    "char": ("B", 1, "int"),
    "uint8": ("B", 1, "int"),
    "int8": ("b", 1, "int"),
    "uint16": ("H", 2, "int"),
    "int16": ("h", 2, "int"),
    "unsigned short": ("H", 2, "int"),
    "short": ("h", 2, "int"),
    "uint32": ("I", 4, "int"),
    "int32": ("i", 4, "int"),
    "unsigned long": ("I", 4, "int"),
    "long": ("i", 4, "int"),
    "uint64": ("Q", 8, "int"),
    "int64": ("q", 8, "int"),
    "unsigned long long": ("Q", 8, "int"),
    "long long": ("q", 8, "int"),
    "float": ("f", 4, "float"),
    "double": ("d", 8, "float"),
}

_ENCAPSULATION = b"\x00\x01"  # CDR_LE
_cache: dict[type, Callable[[bytes], Any] | None] = {}


def _finite(x: float) -> float | None:
    return x if x - x == 0.0 else None  # NaN and infinities are no JSON (to_plain gives None)


_U32 = struct.Struct("<I").unpack_from


def _string(b: memoryview, o: int) -> tuple[str, int]:
    """The string at `o` (4-aligned: uint32 length with its NUL, then UTF-8) and the offset after it."""
    n: int = _U32(b, o)[0]
    return (str(b[o + 4 : o + 3 + n], "utf-8") if n > 1 else ""), o + 4 + n


def _floats(values: tuple[float, ...]) -> list[float | None]:
    total = sum(values)
    if total - total == 0.0:  # all finite (an overflow to infinity only costs the slow path)
        return list(values)
    return [v if v - v == 0.0 else None for v in values]


class _Unsupported(Exception):
    """A type the decoder does not read (wide strings): the caller deserializes the usual way."""


def _import_class(module: str, name: str) -> type:
    cls: type = getattr(importlib.import_module(module), name)
    return cls


def _message_class(named: Any) -> type:
    return _import_class(".".join(named.namespaces), named.name)


def _fields(cls: type) -> list[tuple[str, Any]]:
    get = getattr(cls, "get_fields_and_field_types", None)
    slot_types = getattr(cls, "SLOT_TYPES", None)
    if not callable(get) or slot_types is None:
        raise _Unsupported(f"{cls.__name__} is not a rosidl message class")
    names = list(get())
    if len(names) != len(slot_types):
        raise _Unsupported(f"{cls.__name__}: fields and SLOT_TYPES differ")
    for name in names:
        if not name.isidentifier():
            raise _Unsupported(f"{cls.__name__}: field name {name!r}")
    return list(zip(names, slot_types, strict=True))


class _Function:
    """The source of one decoder function `def NAME(b, o): ... return VALUE, o`, built field by field."""

    def __init__(self, unit: _Unit, name: str, align: int | None) -> None:
        self.unit = unit
        self.name = name
        self.lines: list[str] = []
        self.align = align  # what is known of o % 8 here (None: nothing)
        self.run: list[tuple[str, int, int]] = []  # pending fixed-size items: (format char, size, count)
        self.run_var = ""
        self.run_len = 0  # values in the pending run

    # -- alignment and fixed-size runs ------------------------------------------------------------------------

    def pad(self, size: int) -> None:
        """Align o to `size` (1, 2, 4 or 8)."""
        if size == 1:
            return
        if self.align is None:
            self.lines.append(f"o += -o & {size - 1}")
            self.align = 0 if size == 8 else None
            return
        gap = -self.align % size
        if gap:
            self.lines.append(f"o += {gap}")
        self.align = (self.align + gap) % 8

    def fixed(self, char: str, size: int, count: int) -> str:
        """Queue `count` values of one basic type; their expression (a tuple element or slice)."""
        if not self.run:
            self.run_var = self.unit.new_name("t")
            self.run_len = 0
        self.run.append((char, size, count))
        start = self.run_len
        self.run_len += count
        return f"{self.run_var}[{start}]" if count == 1 else f"{self.run_var}[{start}:{self.run_len}]"

    def flush(self) -> None:
        """Read the pending run with one Struct (one per possible offset modulo 8 when o is unknown here)."""
        if not self.run:
            return
        items, self.run = self.run, []
        layouts = {r: _layout(items, r) for r in range(8)}
        if self.align is not None:
            fmt, size = layouts[self.align]
            struct_name = self.unit.constant(struct.Struct(fmt))
            self.lines.append(f"{self.run_var} = {struct_name}.unpack_from(b, o)")
            self.lines.append(f"o += {size}")
            self.align = (self.align + size) % 8
            return
        structs = tuple(struct.Struct(layouts[r][0]) for r in range(8))
        table = self.unit.constant(structs)
        self.lines.append(f"s = {table}[o & 7]")
        self.lines.append(f"{self.run_var} = s.unpack_from(b, o)")
        self.lines.append("o += s.size")
        ends = {(r + layouts[r][1]) % 8 for r in range(8)}
        self.align = ends.pop() if len(ends) == 1 else None

    # -- values ---------------------------------------------------------------------------------------------

    def value(self, slot: Any) -> str:
        """Read one field of rosidl type `slot`; the expression of its plain value."""
        kind = type(slot).__name__
        if kind == "BasicType":
            char, size, what = _basic(slot)
            return _one(what, self.fixed(char, size, 1))
        if kind in ("UnboundedString", "BoundedString"):
            return self.string()
        if kind in ("UnboundedWString", "BoundedWString"):
            raise _Unsupported("wide strings")
        if kind == "NamespacedType":
            return self.message(_message_class(slot))
        if kind == "Array":
            return self.array(slot.value_type, int(slot.size))
        if kind in ("UnboundedSequence", "BoundedSequence"):
            return self.sequence(slot.value_type)
        raise _Unsupported(f"rosidl type {kind}")

    def message(self, cls: type) -> str:
        """Read a whole message here (nested messages inline, so fixed-size fields join one run)."""
        fields = _fields(cls)
        if not fields:  # an empty message still has one uint8 on the wire (rosidl's placeholder member)
            self.fixed("B", 1, 1)
            return "{}"
        parts = [f"{name!r}: {self.value(slot)}" for name, slot in fields]
        return "{" + ", ".join(parts) + "}"

    def string(self) -> str:
        self.flush()
        self.pad(4)
        v = self.unit.new_name("v")
        self.lines.append(f"{v}, o = string(b, o)")
        self.align = None
        return v

    def element_loop(self, value_type: Any, count: str) -> str:
        """A list of `count` elements read one by one (strings, messages)."""
        v = self.unit.new_name("v")
        kind = type(value_type).__name__
        if kind in ("UnboundedString", "BoundedString"):
            self.lines.append(f"{v} = []")
            self.lines.append(f"for _ in range({count}):")
            self.lines.append("    x, o = string(b, o + (-o & 3))")
            self.lines.append(f"    {v}.append(x)")
        elif kind == "NamespacedType":
            fn = self.unit.function(_message_class(value_type))
            self.lines.append(f"{v} = []")
            self.lines.append(f"for _ in range({count}):")
            self.lines.append(f"    x, o = {fn}(b, o)")
            self.lines.append(f"    {v}.append(x)")
        elif kind in ("UnboundedWString", "BoundedWString"):
            raise _Unsupported("wide strings")
        else:
            raise _Unsupported(f"sequence of {kind}")
        self.align = None
        return v

    def array(self, value_type: Any, size: int) -> str:
        if type(value_type).__name__ == "BasicType":
            char, width, what = _basic(value_type)
            return _many(what, self.fixed(char, width, size))
        self.flush()
        return self.element_loop(value_type, str(size))

    def sequence(self, value_type: Any) -> str:
        self.flush()
        self.pad(4)
        n = self.unit.new_name("n")
        self.lines.append(f"{n} = U32(b, o)[0]")
        self.lines.append("o += 4")
        self.align = (self.align + 4) % 8 if self.align is not None else None
        if type(value_type).__name__ != "BasicType":
            return self.element_loop(value_type, n)
        char, width, what = _basic(value_type)
        v = self.unit.new_name("v")
        self.lines.append(f"if {n}:")
        if width > 1:
            self.lines.append(f"    o += -o & {width - 1}")
        self.lines.append(f"    {v} = unpack_from('<%d{char}' % {n}, b, o)")
        self.lines.append(f"    o += {n} * {width}" if width > 1 else f"    o += {n}")
        self.lines.append("else:")
        self.lines.append(f"    {v} = ()")
        self.align = None
        return _many(what, v)

    def source(self, value: str) -> str:
        self.flush()
        body = "\n".join(f"    {line}" for line in [*self.lines, f"return {value}, o"])
        return f"def {self.name}(b, o):\n{body}\n"


class _Unit:
    """Every function and constant of one decoder."""

    def __init__(self) -> None:
        self.functions: dict[type, str] = {}
        self.sources: list[str] = []
        self.constants: dict[str, Any] = {}
        self._names = 0

    def new_name(self, prefix: str) -> str:
        self._names += 1
        return f"{prefix}{self._names}"

    def constant(self, value: Any) -> str:
        name = self.new_name("S")
        self.constants[name] = value
        return name

    def function(self, cls: type, align: int | None = None) -> str:
        """The name of the function that reads one `cls` message at any offset (made once per class)."""
        name = self.functions.get(cls)
        if name is None:
            name = self.functions[cls] = self.new_name("m")
            fn = _Function(self, name, align)
            value = fn.message(cls)
            self.sources.append(fn.source(value))
        return name


def _basic(slot: Any) -> tuple[str, int, str]:
    found = _BASIC.get(slot.typename)
    if found is None:
        raise _Unsupported(f"basic type {slot.typename}")
    return found


def _one(what: str, expr: str) -> str:
    if what == "float":
        return f"finite({expr})"
    if what == "octet":
        return f"[{expr}]"  # rosidl gives a byte as bytes of length 1, to_plain as [n]
    return expr


def _many(what: str, expr: str) -> str:
    if what == "float":
        return f"floats({expr})"
    if what == "octet":
        return f"[[x] for x in {expr}]"
    return f"list({expr})"


def _layout(items: list[tuple[str, int, int]], start: int) -> tuple[str, int]:
    """A struct format (little-endian, explicit padding) for `items` read from an offset ≡ `start` (mod 8)."""
    fmt, at = ["<"], start
    for char, size, count in items:
        gap = -at % size
        if gap:
            fmt.append(f"{gap}x")
        fmt.append(f"{count}{char}" if count > 1 else char)
        at += gap + size * count
    return "".join(fmt), at - start


def _compile(cls: type) -> Callable[[bytes], Any]:
    unit = _Unit()
    top = unit.function(cls, align=0)
    source = "\n".join(unit.sources)
    namespace: dict[str, Any] = {
        **unit.constants,
        "U32": _U32,
        "string": _string,
        "unpack_from": struct.unpack_from,
        "finite": _finite,
        "floats": _floats,
    }
    exec(compile(source, f"<cdr decoder of {cls.__module__}.{cls.__name__}>", "exec"), namespace)  # noqa: S102
    read = namespace[top]

    def decode(data: bytes) -> Any:
        if data[:2] != _ENCAPSULATION:
            raise CdrError(f"not little-endian classic CDR (encapsulation {bytes(data[:2]).hex()})")
        body = memoryview(data)[4:]
        try:
            value, end = read(body, 0)
        except (struct.error, UnicodeDecodeError, MemoryError) as exc:
            raise CdrError(f"not a {cls.__name__} message: {exc}") from None
        if end > len(body):
            raise CdrError(f"not a {cls.__name__} message: {end - len(body)} bytes missing")
        return value

    decode.__doc__ = f"{cls.__name__} CDR bytes → the values genport.to_plain gives (source: `source`)."
    decode.source = source  # type: ignore[attr-defined]  # for reading and for tests
    return decode


def decoder(cls: type) -> Callable[[bytes], Any] | None:
    """The decoder of rosidl message class `cls` (made once), or None when it has fields this module does
    not read (wide strings): deserialize those the usual way."""
    if cls not in _cache:
        try:
            _cache[cls] = _compile(cls)
        except (_Unsupported, ImportError, AttributeError):
            _cache[cls] = None
    return _cache[cls]


def message_class(type_name: str) -> type | None:
    """The rosidl Python class of `pkg/msg/Name` (None when it cannot be imported here)."""
    package, _, name = type_name.partition("/msg/")
    if not package or not name:
        return None
    try:
        cls = _import_class(f"{package}.msg", name)
    except (ImportError, AttributeError):
        return None
    return cls if isinstance(cls, type) else None


def plain_reader(cls: type) -> Callable[[bytes], Any]:
    """Serialized `cls` messages → the values `genport.to_plain` gives: the compiled decoder, and rclpy's own
    deserialization for what it does not read (wide strings, big-endian or XCDR2 data)."""
    from rclpy.serialization import deserialize_message

    from td2adaptor.runtime.ros.genport import to_plain

    decode = decoder(cls)

    def slow(data: bytes) -> Any:
        return to_plain(deserialize_message(data, cls))

    if decode is None:
        return slow

    def read(data: bytes) -> Any:
        try:
            return decode(data)
        except CdrError:
            return slow(data)

    return read
