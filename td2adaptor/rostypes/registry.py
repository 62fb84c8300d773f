"""Which ROS interface types exist, and what they contain, for one ROS distribution.

Three layers, later ones overriding earlier ones: the rosbags typestore of the distribution (ROS 1 Noetic or
ROS 2 Jazzy: messages only), the service definitions bundled with td2adaptor (`interfaces/`, for standard
packages such as std_srvs that no typestore has), and the user's interface folders.

Interface files are parsed here rather than by rosbags: rosbags cannot read `.srv`/`.action` files, reports
errors without line numbers, drops ROS 2 default values and turns string constants such as `"1"` into
numbers; ROS 1 md5 sums hash constants exactly as written, so the written text is kept.

rosbags is imported lazily (it costs tens of milliseconds) and each typestore is built once per process.
"""

from __future__ import annotations

import difflib
import hashlib
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, cast

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.model import (
    ActionDef,
    ArrayKind,
    Constant,
    FieldType,
    MessageDef,
    MessageField,
    ServiceDef,
    TypeTable,
)
from td2adaptor.rostypes.names import (
    ACTION_PARTS,
    KINDS,
    SERVICE_PARTS,
    Kind,
    is_valid_package_name,
    is_valid_type_name,
    parse_type_name,
    ros1_name,
)
from td2adaptor.rostypes.primitives import FLOATS, STRINGS
from td2adaptor.rostypes.primitives import INT_RANGES as _INT_RANGES

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

Distro = Literal["ros1", "ros2"]
Resolved = MessageDef | ServiceDef | ActionDef

CODES: dict[str, str] = {
    "TY500": "interface folder not found",
    "TY501": "interface folder contains no .msg/.srv/.action files",
    "TY502": "interface package or file name is not a valid ROS name",
    "TY503": "interface file cannot be read",
    "TY510": "syntax error in interface file",
    "TY511": "invalid field type",
    "TY512": "invalid constant",
    "TY513": "duplicate field or constant name",
    "TY514": "wrong number of '---' separators for the file kind",
    "TY515": "field default values are a ROS 2 feature; ignored for ROS 1",
    "TY516": "invalid field default value",
    "TY517": "name is accepted by ROS 1 but rejected by ROS 2 (rosidl)",
    "TY520": "field uses an undefined type",
    "TY521": "messages contain each other (recursive definition)",
    "TY530": "user definition replaces a different typestore definition of the same name",
    "TY531": "interface definition replaces a different earlier definition of the same name",
}

BUNDLED_DIR = Path(__file__).resolve().parent / "interfaces"

_STORE_NAMES: dict[Distro, str] = {"ros1": "ROS1_NOETIC", "ros2": "ROS2_JAZZY"}

_FLOATS = FLOATS
_STRINGS = STRINGS
PRIMITIVES = frozenset({"bool", "byte", *_INT_RANGES, *_FLOATS, *_STRINGS})
_TIME_TYPES = {"time": "builtin_interfaces/msg/Time", "duration": "builtin_interfaces/msg/Duration"}
_TIME_MESSAGES = {v: k for k, v in _TIME_TYPES.items()}
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


# ---------------------------------------------------------------------------------------------------------
# typestores (one per process and distribution)


@cache
def _base_store(distro: Distro) -> Typestore:
    """The rosbags typestore of `distro`; shared, so never mutated."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores[_STORE_NAMES[distro]])


@cache
def _base_fielddefs(distro: Distro) -> dict[str, Any]:
    """The typestore's field definitions as plain data.

    Building a rosbags typestore generates a dataclass per type (~80 ms a distro); the definitions alone are
    cached on disk, keyed by the installed rosbags store module, so a CLI run needs the typestore only for
    serialisation.
    """
    import importlib.util

    from td2adaptor.support import cache

    key = ""
    spec = importlib.util.find_spec("rosbags")
    if spec is not None and spec.submodule_search_locations:
        module = Path(next(iter(spec.submodule_search_locations))) / "typesys" / "stores"
        module = module / f"{_STORE_NAMES[distro].lower()}.py"
        try:
            st = module.stat()
            key = f"rosbags-{_STORE_NAMES[distro].lower()}-{st.st_size}-{int(st.st_mtime)}.json"
        except OSError:
            key = ""
    if key:
        cached = cache.read_json(key)
        if isinstance(cached, dict):
            return cached
    data = {
        name: [[list(c) for c in consts], [[fname, _plain_desc(desc)] for fname, desc in fields]]
        for name, (consts, fields) in _base_store(distro).fielddefs.items()
    }
    if key:
        cache.write_json(key, data)
    return data


def _plain_desc(desc: Any) -> Any:
    node, args = desc
    if int(node) in (3, 4):
        return [int(node), [_plain_desc(args[0]), int(args[1])]]
    if int(node) == 2:
        return [2, str(args)]
    return [int(node), [str(args[0]), int(args[1])]]


_BASE_DEFS: dict[tuple[Distro, str], MessageDef] = {}


def _convert_desc(desc: Any, distro: Distro) -> FieldType:
    """A rosbags field descriptor `(Nodetype, args)` → FieldType (Nodetype is an IntEnum: 1..4)."""
    node, args = desc
    if node in (3, 4):  # ARRAY, SEQUENCE
        inner_desc, size = args
        inner = _convert_desc(inner_desc, distro)
        kind = ArrayKind.FIXED if node == 3 else ArrayKind.SEQUENCE
        return FieldType(inner.base, inner.is_message, kind, int(size), inner.string_bound)
    if node == 2:  # NAME
        name = str(args)
        if distro == "ros1" and name in _TIME_MESSAGES:
            return FieldType(_TIME_MESSAGES[name])
        return FieldType(name, is_message=True)
    base, bound = args
    return FieldType(str(base), string_bound=int(bound) if base in _STRINGS else 0)


def _base_message(distro: Distro, name: str) -> MessageDef | None:
    """A typestore message as a model MessageDef (converted once per process)."""
    key = (distro, name)
    found = _BASE_DEFS.get(key)
    if found is not None:
        return found
    if distro == "ros1" and name in _TIME_MESSAGES:
        return None  # ROS 1 has `time`/`duration` primitives, no builtin_interfaces package
    fielddefs = _base_fielddefs(distro).get(name)
    if fielddefs is None:
        return None
    consts, fields = fielddefs
    msg = MessageDef(
        name,
        tuple(
            MessageField(fname, _convert_desc(desc, distro))
            for fname, desc in fields
            if fname != "structure_needs_at_least_one_member"
        ),
        tuple(Constant(cname, str(ctype), cvalue) for cname, ctype, cvalue in consts),
        origin=f"rosbags:{_STORE_NAMES[distro].lower()}",
    )
    _BASE_DEFS[key] = msg
    return msg


# ---------------------------------------------------------------------------------------------------------
# interface file parsing


@dataclass(frozen=True)
class _Def:
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


class _FileParser:
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
        elif base in _TIME_TYPES:
            if self.distro == "ros2":
                base, is_message = _TIME_TYPES[base], True
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
            self.report("TY515", CODES["TY515"], lineno, col, severity=Severity.WARNING)
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

    def section(self, name: str, lines: Sequence[tuple[int, str]]) -> _Def:
        """One message (a whole .msg, or one part of a .srv/.action) from its numbered lines."""
        fields: list[MessageField] = []
        field_lines: list[int] = []
        constants: list[Constant] = []
        texts: list[str] = []
        field_names: set[str] = set()
        constant_names: set[str] = set()
        for lineno, line in lines:
            code = _strip_comment(line).strip()
            if not code:
                continue
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
            fields.append(MessageField(fname, ftype, default))
            field_lines.append(lineno)
        msg = MessageDef(name, tuple(fields), tuple(constants), origin=self.origin)
        return _Def(msg, tuple(texts), tuple(field_lines), self.file)

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


def _split_sections(text: str) -> tuple[list[list[tuple[int, str]]], list[int]]:
    """Numbered lines of each `---`-separated section, and the line numbers of the separators."""
    sections: list[list[tuple[int, str]]] = [[]]
    separators: list[int] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        if _SEPARATOR.fullmatch(line):
            sections.append([])
            separators.append(lineno)
        else:
            sections[-1].append((lineno, line))
    return sections, separators


_PART_SUFFIXES: dict[Kind, tuple[str, ...]] = {
    "msg": ("",),
    "srv": tuple(SERVICE_PARTS.values()),
    "action": tuple(ACTION_PARTS.values()),
}


# ---------------------------------------------------------------------------------------------------------
# the registry


class TypeRegistry:
    """Resolves canonical type names (`pkg/msg/Name`, `pkg/srv/Name`, `pkg/action/Name`) for one distro.

    Services are stored as two messages `pkg/srv/Name_Request` / `_Response`, actions as
    `pkg/action/Name_Goal` / `_Result` / `_Feedback`. Problems in interface folders go to `diags` while the
    registry is built; a definition with errors is left out (and types using it are not reported again).
    """

    def __init__(
        self,
        distro: Distro,
        interface_dirs: Sequence[Path] = (),
        diags: Diagnostics | None = None,
    ) -> None:
        if distro not in _STORE_NAMES:
            raise ValueError(f"unknown ROS distribution {distro!r}: expected 'ros1' or 'ros2'")
        self.distro: Distro = distro
        self.diags = diags if diags is not None else Diagnostics()
        self._defs: dict[str, _Def] = {}
        self._services: dict[str, tuple[str, str]] = {}
        self._actions: dict[str, tuple[str, str, str]] = {}
        self._broken: set[str] = set()
        self._known: tuple[str, ...] | None = None
        self._md5s: dict[str, str] = {}
        self._typestore: Typestore | None = None
        self._load_dir(BUNDLED_DIR, bundled=True)
        for directory in interface_dirs:
            self._load_dir(Path(directory), bundled=False)
        self._check_references()

    # -- loading ----------------------------------------------------------------------------------------

    def _folder_error(self, code: str, message: str, path: Path, severity: Severity) -> None:
        self.diags.append(Diagnostic(code, severity, message, "", None, str(path)))

    def _load_dir(self, root: Path, *, bundled: bool) -> None:
        if not root.is_dir():
            self._folder_error("TY500", f"interface folder not found: {root}", root, Severity.ERROR)
            return
        if (root / "package.xml").is_file() or any((root / kind).is_dir() for kind in KINDS):
            packages = [root]
        else:
            packages = sorted(p for p in root.iterdir() if p.is_dir() and any((p / k).is_dir() for k in KINDS))
        found = False
        for pkg_dir in packages:
            package = pkg_dir.resolve().name
            if not is_valid_package_name(package):
                self._folder_error(
                    "TY502",
                    f"invalid package name {package!r} (lower-case letters, digits and _, letter first)",
                    pkg_dir,
                    Severity.ERROR,
                )
                found = True
                continue
            for kind in KINDS:
                files = sorted((pkg_dir / kind).glob(f"*.{kind}")) if (pkg_dir / kind).is_dir() else []
                for path in files:
                    found = True
                    self._load_file(path, package, kind, bundled=bundled)
        if not found:
            self._folder_error(
                "TY501",
                f"no <pkg>/msg/*.msg, <pkg>/srv/*.srv or <pkg>/action/*.action files under {root}",
                root,
                Severity.WARNING,
            )

    def _load_file(self, path: Path, package: str, kind: Kind, *, bundled: bool) -> None:
        origin = f"td2adaptor:{path.relative_to(BUNDLED_DIR).as_posix()}" if bundled else None
        parser = _FileParser(path, package, self.distro, self.diags, origin)
        stem = path.name[: -len(kind) - 1]
        if not is_valid_type_name(stem):
            parser.report("TY502", f"invalid type name {stem!r} (CamelCase letters and digits)")
            return
        name = f"{package}/{kind}/{stem}"
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            parser.report("TY503", f"cannot read {path}: {exc}")
            self._broken.add(name)
            return
        sections, separators = _split_sections(text)
        suffixes = _PART_SUFFIXES[kind]
        if len(sections) != len(suffixes):
            line = separators[len(suffixes) - 1] if len(separators) >= len(suffixes) else None
            parser.report(
                "TY514",
                f"a .{kind} file needs {len(suffixes) - 1} '---' separator line(s), found {len(separators)}",
                line,
            )
            self._broken.add(name)
            return
        defs = [parser.section(f"{name}{suffix}", lines) for suffix, lines in zip(suffixes, sections, strict=True)]
        if not parser.ok:
            self._broken.update([name, *(d.msg.name for d in defs)])
            return
        self._warn_if_replacing(name, defs, parser, bundled)
        for d in defs:
            self._defs[d.msg.name] = d
            self._broken.discard(d.msg.name)
        self._broken.discard(name)
        if kind == "srv":
            self._services[name] = (defs[0].msg.name, defs[1].msg.name)
        elif kind == "action":
            self._actions[name] = (defs[0].msg.name, defs[1].msg.name, defs[2].msg.name)

    def _warn_if_replacing(self, name: str, defs: Sequence[_Def], parser: _FileParser, bundled: bool) -> None:
        """Overriding is allowed, but a silently different definition would change behaviour and md5s."""
        for d in defs:
            earlier = self._defs.get(d.msg.name)
            if earlier is not None:
                if earlier.msg != d.msg:
                    parser.report(
                        "TY531",
                        f"{name} replaces a different definition from {earlier.file}",
                        severity=Severity.WARNING,
                    )
                    return
                continue
            if bundled:
                continue
            base = _base_message(self.distro, d.msg.name)
            if base is not None and base != d.msg:
                store = _STORE_NAMES[self.distro].lower()
                parser.report(
                    "TY530",
                    f"{name} replaces the different {store} definition of the same name",
                    hint="rename the type if it is not meant to be the standard one",
                    severity=Severity.WARNING,
                )
                return

    def _check_references(self) -> None:
        """Every message type used in an interface file must exist, and no message may contain itself."""
        for name, d in self._defs.items():
            if name in self._broken:
                continue
            for fld, line in zip(d.msg.fields, d.field_lines, strict=True):
                target = fld.type.base
                if not fld.type.is_message or target in self._broken or self._message(target) is not None:
                    continue
                similar = self.closest(target)
                self.diags.append(
                    Diagnostic(
                        "TY520",
                        Severity.ERROR,
                        f"field {fld.name!r} of {name} uses undefined type {target}",
                        "",
                        f"did you mean {', '.join(similar)}?" if similar else "add its definition",
                        d.file,
                        line,
                    )
                )
        self._check_cycles()
        self._known = None

    def _check_cycles(self) -> None:
        state: dict[str, int] = {}  # 1 = on the DFS stack, 2 = done

        def visit(name: str, path: list[str]) -> None:
            state[name] = 1
            msg = self._message(name)
            for fld in msg.fields if msg is not None else ():
                target = fld.type.base
                if not fld.type.is_message:
                    continue
                if state.get(target) == 1:
                    self._report_cycle(path[path.index(target) :])
                elif target not in state:
                    visit(target, [*path, target])
            state[name] = 2

        for name in list(self._defs):
            if name not in state and name not in self._broken:
                visit(name, [name])

    def _report_cycle(self, cycle: list[str]) -> None:
        user = [n for n in cycle if n in self._defs and n not in self._broken]
        if not user:
            return
        first = self._defs[user[0]]
        self.diags.append(
            Diagnostic(
                "TY521",
                Severity.ERROR,
                f"recursive message definition: {' -> '.join([*cycle, cycle[0]])}",
                "",
                "a message cannot contain itself, not even through other messages",
                first.file,
                first.field_lines[0] if first.field_lines else None,
            )
        )
        self._broken.update(user)

    # -- lookup -----------------------------------------------------------------------------------------

    def _message(self, name: str) -> MessageDef | None:
        if name in self._broken:
            return None
        found = self._defs.get(name)
        if found is not None:
            return found.msg
        return _base_message(self.distro, name)

    def resolve(self, name: str) -> Resolved | None:
        """The definition of a canonical name (message, service, action or one of their parts), or None."""
        if name in self._broken:
            return None
        if name in self._services:
            req, resp = (self._message(n) for n in self._services[name])
            return ServiceDef(name, req, resp) if req is not None and resp is not None else None
        if name in self._actions:
            goal, result, feedback = (self._message(n) for n in self._actions[name])
            if goal is None or result is None or feedback is None:
                return None
            return ActionDef(name, goal, result, feedback)
        return self._message(name)

    def known_names(self, kind: Kind | None = None) -> list[str]:
        """Sorted canonical names of all messages, services and actions (not their parts)."""
        if self._known is None:
            names: set[str] = set(self._services) | set(self._actions)
            names.update(n for n in self._defs if "/msg/" in n)
            names.update(n for n in _base_fielddefs(self.distro) if "/msg/" in n)
            if self.distro == "ros1":
                names.difference_update(_TIME_MESSAGES)
            names.difference_update(self._broken)
            self._known = tuple(sorted(names))
        if kind is None:
            return list(self._known)
        return [n for n in self._known if f"/{kind}/" in n]

    def closest(self, name: str, n: int = 3) -> list[str]:
        """Known names resembling `name`, best first: same type name in another package, then by spelling."""
        parsed = parse_type_name(name)
        query = parsed.canonical if parsed is not None else name.strip()
        known = self.known_names()
        short = re.split(r"[/.]", query)[-1].lower()
        out = sorted((k for k in known if k.rsplit("/", 1)[-1].lower() == short), key=lambda k: (k != query, k))
        lowered = {k.lower(): k for k in known}
        out += [lowered[m] for m in difflib.get_close_matches(query.lower(), list(lowered), n=n, cutoff=0.6)]
        return list(dict.fromkeys(out))[:n]

    def table(self, names: Sequence[str]) -> TypeTable:
        """The named types plus every message they use, in depth-first first-use order; unknowns → missing."""
        messages: dict[str, MessageDef] = {}
        services: dict[str, ServiceDef] = {}
        actions: dict[str, ActionDef] = {}
        missing: dict[str, None] = {}

        def visit(msg: MessageDef) -> None:
            for fld in msg.fields:
                if not fld.type.is_message or fld.type.base in messages:
                    continue
                sub = self._message(fld.type.base)
                if sub is None:
                    missing[fld.type.base] = None
                else:
                    messages[sub.name] = sub
                    visit(sub)

        for name in names:
            if name in messages or name in services or name in actions:
                continue
            found = self.resolve(name)
            if found is None:
                missing[name] = None
            elif isinstance(found, ServiceDef):
                services[name] = found
                visit(found.request)
                visit(found.response)
            elif isinstance(found, ActionDef):
                actions[name] = found
                for part in (found.goal, found.result, found.feedback):
                    visit(part)
            else:
                messages[name] = found
                visit(found)
        return TypeTable(
            self.distro,
            tuple(messages.values()),
            tuple(services.values()),
            tuple(actions.values()),
            tuple(missing),
        )

    # -- ROS 1 definitions and md5 sums -----------------------------------------------------------------

    def _constant_texts(self, name: str, msg: MessageDef) -> Iterable[str]:
        found = self._defs.get(name)
        if found is not None:
            return found.const_texts
        return (f"{c.value}" for c in msg.constants)

    def _require(self, name: str, user: str) -> MessageDef:
        msg = self._message(name)
        if msg is None:
            raise KeyError(f"{user} uses unknown type {name}" if user != name else f"unknown type {name}")
        return msg

    def _own_text(self, name: str) -> str:
        """The ROS 1 text of one message without its dependencies (`time`, `pkg/Name` spellings)."""
        msg = self._require(name, name)
        lines = [f"{c.type} {c.name}={t}" for c, t in zip(msg.constants, self._constant_texts(name, msg), strict=True)]
        for fld in msg.fields:
            ftype = fld.type
            spelled = FieldType(ros1_name(ftype.base), False, ftype.array, ftype.length) if ftype.is_message else ftype
            lines.append(f"{spelled} {fld.name}")
        return "".join(f"{line}\n" for line in lines)

    def _md5_text(self, name: str) -> str:
        """genmsg's md5 text: constants as written, then fields, nested messages replaced by their md5."""
        msg = self._require(name, name)
        lines = [f"{c.type} {c.name}={t}" for c, t in zip(msg.constants, self._constant_texts(name, msg), strict=True)]
        for fld in msg.fields:
            if fld.type.is_message:
                self._require(fld.type.base, name)
                lines.append(f"{self._md5(fld.type.base)} {fld.name}")
            else:
                lines.append(f"{fld.type} {fld.name}")
        return "\n".join(lines)

    def _md5(self, name: str) -> str:
        found = self._md5s.get(name)
        if found is None:
            found = hashlib.md5(self._md5_text(name).encode()).hexdigest()
            self._md5s[name] = found
        return found

    def ros1_definition(self, name: str) -> tuple[str, str]:
        """ROS 1 full definition text and md5 sum of a message or service (ros1 registries only).

        Messages: the text rospy/rosbag put in connection headers (the message, then each message it uses
        after a `====...` line and `MSG: pkg/Name`). Services: request and response texts around `---`, and
        genpy's service md5 (one md5 over the request and response md5 texts). KeyError for unknown types or
        types using unknown types.
        """
        if self.distro != "ros1":
            raise ValueError("ROS 1 definitions need a ros1 registry")
        if name in self._services and name not in self._broken:
            req, resp = self._services[name]
            digest = hashlib.md5((self._md5_text(req) + self._md5_text(resp)).encode()).hexdigest()
            return f"{self._own_text(req)}---\n{self._own_text(resp)}", digest
        digest = self._md5(name)
        deps: dict[str, None] = {}

        def collect(msg_name: str) -> None:
            for fld in self._require(msg_name, msg_name).fields:
                if fld.type.is_message and fld.type.base not in deps:
                    deps[fld.type.base] = None
                    collect(fld.type.base)

        collect(name)
        parts = [self._own_text(name)]
        parts += [f"{'=' * 80}\nMSG: {ros1_name(dep)}\n{self._own_text(dep)}" for dep in deps]
        return "".join(parts), digest

    # -- rosbags typestore with the user's types --------------------------------------------------------

    def typestore(self) -> Typestore:
        """A rosbags typestore of this distro plus every complete user/bundled type (for serialisation).

        Built on first use (it generates code); the per-process base typestore itself stays untouched.
        """
        if self._typestore is None:
            from rosbags.typesys.store import Typestore as RosbagsTypestore

            base = _base_store(self.distro)
            store = RosbagsTypestore()
            store.fielddefs.update(base.fielddefs)
            store.types.update(base.types)
            usable = [n for n in self._defs if self._complete(n)]
            for name in usable:
                store.fielddefs.pop(name, None)
                store.types.pop(name, None)
            if usable:
                typs = {name: self._to_rosbags(self._defs[name].msg) for name in usable}
                store.register(cast(Any, typs))
            self._typestore = store
        return self._typestore

    def _complete(self, name: str, seen: set[str] | None = None) -> bool:
        """Whether `name` and everything it uses resolves."""
        seen = set() if seen is None else seen
        if name in seen:
            return True
        seen.add(name)
        msg = self._message(name)
        if msg is None:
            return False
        return all(self._complete(f.type.base, seen) for f in msg.fields if f.type.is_message)

    def _to_rosbags(self, msg: MessageDef) -> tuple[list[tuple[str, str, Any]], list[tuple[str, Any]]]:
        from rosbags.interfaces import Nodetype

        def desc(ftype: FieldType) -> Any:
            inner: tuple[Any, Any]
            if ftype.is_message:
                inner = (Nodetype.NAME, ftype.base)
            elif ftype.base in _TIME_TYPES:
                inner = (Nodetype.NAME, _TIME_TYPES[ftype.base])
            else:
                inner = (Nodetype.BASE, (ftype.base, ftype.string_bound))
            if ftype.array is ArrayKind.NONE:
                return inner
            node = Nodetype.ARRAY if ftype.array is ArrayKind.FIXED else Nodetype.SEQUENCE
            return (node, (inner, ftype.length))

        consts = [(c.name, c.type, c.value) for c in msg.constants]
        return consts, [(f.name, desc(f.type)) for f in msg.fields]
