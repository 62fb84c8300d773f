"""Parsing `.msg`/`.srv`/`.action` interface files into model messages, reporting problems with file:line:col.

Interface files are parsed here rather than by rosbags: rosbags cannot read `.srv`/`.action` files, reports
errors without line numbers, drops ROS 2 default values and turns string constants such as `"1"` into
numbers; ROS 1 md5 sums hash constants exactly as written, so the written text is kept.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.diagnostics.catalogue import meaning
from td2adaptor.model import ArrayKind, Constant, FieldType, MessageDef, MessageField
from td2adaptor.model.primitives import FLOATS as _FLOATS
from td2adaptor.model.primitives import INT_RANGES as _INT_RANGES
from td2adaptor.model.primitives import STRINGS as _STRINGS
from td2adaptor.rostypes.names import ACTION_PARTS, SERVICE_PARTS, Kind, is_valid_package_name, is_valid_type_name
from td2adaptor.rostypes.typestore import TIME_TYPES, Distro

PRIMITIVES = frozenset({"bool", "byte", *_INT_RANGES, *_FLOATS, *_STRINGS})
_HEADER = "std_msgs/msg/Header"

_TYPE_TOKEN = re.compile(
    r"(?P<base>[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*){0,2})"
    r"(?:<=(?P<sbound>[0-9]+))?(?:\[(?P<array><=[0-9]+|[0-9]*)\])?"
)
_IDENT = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_ROS2_FIELD = re.compile(r"[a-z](?:_?[a-z0-9]+)*")
_ROS2_CONSTANT = re.compile(r"[A-Z](?:_?[A-Z0-9]+)*")
_CONSTANT_DECL = re.compile(r"(?P<name>[A-Za-z][A-Za-z0-9_]*)\s*=\s*(?P<value>.*)")
_SEPARATOR = re.compile(r"\s*---\s*")
_PREFIXED_INT = re.compile(r"[+-]?0(?:[xX][0-9a-fA-F]+|[bB][01]+|[oO][0-7]+)")
_ARRAY_ITEM = re.compile(r"""\s*("(?:\\.|[^"\\])*"|'(?:\\.|[^'\\])*'|[^,]*?)\s*(?:,|$)""")


@dataclass(frozen=True)
class ParsedDef:
    """A message from an interface file, plus what the model does not keep (for md5s and diagnostics)."""

    msg: MessageDef
    const_texts: tuple[str, ...]  # values as written: genmsg hashes the text, not the value
    field_lines: tuple[int, ...]
    file: str


def _strip_comment(line: str) -> str:
    """Cut a `#` comment, ignoring `#` inside quoted literals (ROS 2 string defaults)."""
    quote = ""
    escaped = False
    for i, ch in enumerate(line):
        if escaped:
            escaped = False
        elif ch == "\\" and quote:
            escaped = True
        elif quote:
            if ch == quote:
                quote = ""
        elif ch in "\"'":
            quote = ch
        elif ch == "#":
            return line[:i]
    return line


def _comment_text(text: str) -> str:
    """The words of a comment (`  # Voltage in Volts` → `Voltage in Volts`); "" for no comment."""
    return text.strip().lstrip("#").strip()


def _unquote(text: str) -> str:
    """A quoted ROS 2 string literal → its value; unquoted text is returned as is."""
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
        return re.sub(r"\\(.)", r"\1", text[1:-1])
    return text


def _convert_scalar(typ: str, text: str, distro: Distro) -> Any:
    """One literal of primitive type `typ`; ValueError with a readable reason if it does not fit."""
    if typ == "bool":
        lowered = text.lower()
        if lowered in ("true", "1"):
            return True
        if lowered in ("false", "0"):
            return False
        raise ValueError(f"{text!r} is not a bool (true/false)")
    if typ in _FLOATS:
        try:
            return float(text)
        except ValueError:
            raise ValueError(f"{text!r} is not a {typ}") from None
    if typ in _STRINGS:
        return _unquote(text) if distro == "ros2" else text
    lo, hi = (-(2**7), 2**7 - 1) if typ == "byte" and distro == "ros1" else _INT_RANGES.get(typ, (0, 255))
    try:
        value = int(text, 0) if _PREFIXED_INT.fullmatch(text) else int(text)
    except ValueError:
        raise ValueError(f"{text!r} is not an integer") from None
    if not lo <= value <= hi:
        raise ValueError(f"{value} is out of range for {typ} ({lo}..{hi})")
    return value


class FileParser:
    """Parses the sections of one interface file, reporting problems with file:line:col."""

    def __init__(self, path: Path, package: str, distro: Distro, diags: Diagnostics, origin: str | None = None) -> None:
        self.path = path
        self.file = str(path)
        self.origin = origin or self.file
        self.package = package
        self.distro = distro
        self.diags = diags
        self.ok = True

    def report(
        self,
        code: str,
        message: str,
        line: int | None = None,
        col: int | None = None,
        hint: str | None = None,
        severity: Severity = Severity.ERROR,
    ) -> None:
        if severity is Severity.ERROR:
            self.ok = False
        self.diags.append(Diagnostic(code, severity, message, "", hint, self.file, line, col))

    def field_type(self, token: str, lineno: int, col: int) -> FieldType | None:
        """Resolve a field's type token the way genmsg/rosidl do (relative names, Header, time)."""
        match = _TYPE_TOKEN.fullmatch(token)
        if match is None:
            self.report("TY511", f"invalid field type {token!r}", lineno, col)
            return None
        base, sbound, array = match["base"], match["sbound"], match["array"]
        is_message = False
        if base in PRIMITIVES:
            pass
        elif base in TIME_TYPES:
            if self.distro == "ros2":
                base, is_message = TIME_TYPES[base], True
        elif base == "Header":
            base, is_message = _HEADER, True
        else:
            pieces = base.split("/")
            if len(pieces) == 1:
                pieces = [self.package, "msg", base]
            elif len(pieces) == 2:
                pieces = [pieces[0], "msg", pieces[1]]
            pkg, middle, short = pieces
            if middle != "msg" or not is_valid_package_name(pkg) or not is_valid_type_name(short):
                self.report(
                    "TY511",
                    f"invalid message type name {base!r}",
                    lineno,
                    col,
                    "use `Name` (same package), `pkg/Name` or `pkg/msg/Name` with a CamelCase Name",
                )
                return None
            base, is_message = f"{pkg}/msg/{short}", True
        string_bound = 0
        if sbound is not None:
            if base not in _STRINGS:
                self.report("TY511", f"only strings can be bounded: {token!r}", lineno, col)
                return None
            string_bound = int(sbound)
        kind, length = ArrayKind.NONE, 0
        if array is not None:
            if array.startswith("<="):
                kind, length = ArrayKind.SEQUENCE, int(array[2:])
            elif array:
                kind, length = ArrayKind.FIXED, int(array)
            else:
                kind = ArrayKind.SEQUENCE
            if array and length == 0:
                self.report("TY511", f"array size must be positive: {token!r}", lineno, col)
                return None
        if self.distro == "ros1" and (string_bound or (kind is ArrayKind.SEQUENCE and length)):
            self.report("TY511", f"bounded types are a ROS 2 feature: {token!r}", lineno, col)
            return None
        return FieldType(base, is_message, kind, length, string_bound)

    def default(self, ftype: FieldType, text: str, lineno: int, col: int) -> Any:
        """A ROS 2 field default (`int32 x 5`, `float64[] v [1.0, 2.0]`); None after reporting a problem."""
        if self.distro == "ros1":
            self.report("TY515", meaning("TY515"), lineno, col, severity=Severity.WARNING)
            return None
        if ftype.is_message:
            self.report("TY516", f"message fields cannot have defaults ({ftype})", lineno, col)
            return None
        try:
            if ftype.array is ArrayKind.NONE:
                return self._bounded_string(ftype, _convert_scalar(ftype.base, text, self.distro))
            if not (text.startswith("[") and text.endswith("]")):
                raise ValueError(f"array default must be written [a, b, ...], got {text!r}")
            inner = text[1:-1].strip()
            items = [m[1] for m in _ARRAY_ITEM.finditer(inner) if m[0]] if inner else []
            values = tuple(self._bounded_string(ftype, _convert_scalar(ftype.base, it, "ros2")) for it in items)
            if ftype.array is ArrayKind.FIXED and len(values) != ftype.length:
                raise ValueError(f"{ftype} needs exactly {ftype.length} values, got {len(values)}")
            if ftype.length and len(values) > ftype.length:
                raise ValueError(f"{ftype} allows at most {ftype.length} values, got {len(values)}")
            return values
        except ValueError as exc:
            self.report("TY516", f"invalid default value: {exc}", lineno, col)
            return None

    @staticmethod
    def _bounded_string(ftype: FieldType, value: Any) -> Any:
        if ftype.string_bound and isinstance(value, str) and len(value) > ftype.string_bound:
            raise ValueError(f"{value!r} is longer than {ftype.string_bound} characters")
        return value

    def section(self, name: str, lines: Sequence[tuple[int, str]]) -> ParsedDef:
        """One message (a whole .msg, or one part of a .srv/.action) from its numbered lines."""
        fields: list[MessageField] = []
        field_lines: list[int] = []
        constants: list[Constant] = []
        texts: list[str] = []
        field_names: set[str] = set()
        constant_names: set[str] = set()
        above: list[str] = []  # comment lines right above the current line
        opening = True  # nothing but comments so far: a comment block here is the message's, not a field's
        for lineno, line in lines:
            code = _strip_comment(line).strip()
            if not code:
                if line.strip():
                    above.append(_comment_text(line))
                else:
                    above, opening = [], False
                continue
            leading, above = ([] if opening else above), []
            opening = False
            indent = len(line) - len(line.lstrip())
            pieces = code.split(None, 1)
            token, rest = pieces[0], pieces[1] if len(pieces) > 1 else ""
            rest_col = line.find(rest, indent + len(token)) + 1 if rest else None
            if not rest:
                self.report(
                    "TY510",
                    f"expected `type name`, got {code!r}",
                    lineno,
                    indent + 1,
                    "fields are `type name`, constants `type NAME=value`",
                )
                continue
            decl = _CONSTANT_DECL.fullmatch(rest)
            if decl is not None:
                self._constant(line, token, decl, lineno, indent + 1, rest_col, constants, texts, constant_names)
                continue
            more = rest.split(None, 1)
            fname, default_text = more[0], more[1] if len(more) > 1 else ""
            if not _IDENT.fullmatch(fname):
                self.report("TY510", f"invalid field name {fname!r}", lineno, rest_col)
                continue
            ftype = self.field_type(token, lineno, indent + 1)
            if ftype is None:
                continue
            if fname in field_names:
                self.report("TY513", f"field {fname!r} is defined twice", lineno, rest_col)
                continue
            field_names.add(fname)
            if self.distro == "ros2" and not _ROS2_FIELD.fullmatch(fname):
                self.report(
                    "TY517",
                    f"ROS 2 requires lower_snake_case field names: {fname!r}",
                    lineno,
                    rest_col,
                    severity=Severity.WARNING,
                )
            default = None
            if default_text:
                default_col = line.find(default_text, line.find(fname, indent + len(token)) + len(fname)) + 1
                default = self.default(ftype, default_text, lineno, default_col)
            comment = " ".join(t for t in (*leading, _comment_text(line[len(_strip_comment(line)) :])) if t)
            fields.append(MessageField(fname, ftype, default, comment))
            field_lines.append(lineno)
        msg = MessageDef(name, tuple(fields), tuple(constants), origin=self.origin)
        return ParsedDef(msg, tuple(texts), tuple(field_lines), self.file)

    def _constant(
        self,
        line: str,
        token: str,
        decl: re.Match[str],
        lineno: int,
        col: int,
        rest_col: int | None,
        constants: list[Constant],
        texts: list[str],
        names: set[str],
    ) -> None:
        name = decl["name"]
        if token not in PRIMITIVES:
            self.report("TY512", f"constants must have a primitive type, not {token!r}", lineno, col)
            return
        if token in _STRINGS:
            # ROS 1 (genmsg): everything right of the first `=` is the value, `#` included.
            raw = line[line.index("=") + 1 :].strip()
            if self.distro == "ros2":
                quoted = re.match(r"""("(?:\\.|[^"\\])*"|'(?:\\.|[^'\\])*')""", raw)
                raw = quoted[1] if quoted else decl["value"].strip()
            text = raw
        else:
            text = decl["value"].strip()
        try:
            value = _convert_scalar(token, text, self.distro)
        except ValueError as exc:
            self.report("TY512", f"invalid value of constant {name}: {exc}", lineno, rest_col)
            return
        if name in names:
            self.report("TY513", f"constant {name!r} is defined twice", lineno, rest_col)
            return
        names.add(name)
        if self.distro == "ros2" and not _ROS2_CONSTANT.fullmatch(name):
            self.report(
                "TY517",
                f"ROS 2 requires UPPER_CASE constant names: {name!r}",
                lineno,
                rest_col,
                severity=Severity.WARNING,
            )
        constants.append(Constant(name, token, value))
        texts.append(text)


def split_sections(text: str, *, genmsg: bool = False) -> tuple[list[list[tuple[int, str]]], list[int], list[int]]:
    """Numbered lines of each `---`-separated section, the line numbers of the separators, and those of them
    only ROS 1 accepts: with `genmsg`, any line starting with `---` separates (`-----`, `--- comment`), as
    genmsg reads it; rosidl wants `---` alone."""
    sections: list[list[tuple[int, str]]] = [[]]
    separators: list[int] = []
    loose: list[int] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        strict = _SEPARATOR.fullmatch(line) is not None
        if strict or (genmsg and line.startswith("---")):
            sections.append([])
            separators.append(lineno)
            if not strict:
                loose.append(lineno)
        else:
            sections[-1].append((lineno, line))
    return sections, separators, loose


PART_SUFFIXES: dict[Kind, tuple[str, ...]] = {
    "msg": ("",),
    "srv": tuple(SERVICE_PARTS.values()),
    "action": tuple(ACTION_PARTS.values()),
}
