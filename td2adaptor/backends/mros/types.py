"""ROS 1 message types as C++98 classes for mROS: names, field codecs, wire sizes and traits (the C/C++
names every such backend shares are `_cxx.names`', re-exported here: `PRIMITIVES`, `CPP_KEYWORDS`, `comment`).

Everything the message-header templates print is computed here: C++ names (with deterministic mangling of
names C++ cannot use), the codec of each field (the `td2a::wire` helper that reads/writes it), the exact
wire size of fixed-size types, the minimum wire size (bounds checks when decoding) and a *bounded* maximum
size used to size mROS's memory pools (unbounded strings and sequences count with assumed capacities).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

from td2adaptor.backends._cxx.names import C_MACROS, c_macro_like, mangle
from td2adaptor.backends._cxx.names import CPP_KEYWORDS as CPP_KEYWORDS
from td2adaptor.backends._cxx.names import PRIMITIVES as PRIMITIVES
from td2adaptor.backends._cxx.names import comment as comment
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation import textsafe as ts
from td2adaptor.model import ArrayKind, Constant, FieldType, MessageDef, TypeTable

#: ROS 1 `time`/`duration`: two 32-bit words, as small classes of the support header.
TIME_TYPES: dict[str, str] = {"time": "td2a::Time", "duration": "td2a::Duration"}
#: Macros that the TOPPERS or mROS headers may define, besides the C library's (`_cxx.names.C_MACROS`): a
#: member or class called so gets a trailing '_' (see `macro_like`).
TOPPERS_MACROS = frozenset(
    """E_OK E_SYS E_NOSPT E_RSFN E_RSATR E_PAR E_ID E_CTX E_MACV E_OACV E_ILUSE E_NOMEM E_NOID E_NORES E_OBJ
    E_NOEXS E_QOVR E_RLWAI E_TMOUT E_DLT E_CLS E_WBLK E_BOVR""".split()
)
MACRO_LIKE = C_MACROS | TOPPERS_MACROS
_MACRO_PATTERN = re.compile(r"(?:TA|TMAX|TMIN|TNFY|TKERNEL|TOPPERS|TSK|TTS|TTW|LOG|MROS|ROS|TD2A)_[A-Z0-9_]*")


def macro_like(name: str) -> bool:
    """Whether `name` may be a macro of the headers the generated code includes (or is reserved in C++)."""
    return name in TOPPERS_MACROS or _MACRO_PATTERN.fullmatch(name) is not None or c_macro_like(name)


#: Namespaces the generated code and mROS already use: a ROS package may not become one of them.
RESERVED_NAMESPACES = frozenset({"std", "ros", "message_traits", "subtask_methods", "td2a", "adaptor", "adaptor_hooks"})
#: Members every generated message class has.
MESSAGE_MEMBERS = frozenset({"dataSize", "memCopy", "deserialize", "td2a_read", "td2a_write", "swap"})
#: Decoding: at most this many elements of a zero-size element type (an empty message) per sequence.
MAX_EMPTY_ELEMENTS = 65536
FIRST_MSG_ID = 101  # the range mROS's own generator uses for custom types


@dataclass(frozen=True)
class Capacities:
    """Assumed capacities of unbounded strings (bytes) and sequences (elements), for pool sizing; `fields`
    sets one field's capacity: ((message type, field), bytes of a string field or elements of a sequence)."""

    string: int = 64
    sequence: int = 8
    fields: tuple[tuple[tuple[str, str], int], ...] = ()

    def of(self, owner: str | None, name: str | None) -> int | None:
        """The capacity set for field `name` of `owner`, if one was."""
        return next((cap for key, cap in self.fields if key == (owner, name)), None)


@dataclass(frozen=True)
class WireSize:
    """Minimum and bounded maximum serialised size; `fixed` when every instance has the same size."""

    min: int
    max: int
    fixed: bool
    unbounded: bool  # max relies on assumed capacities


@dataclass(frozen=True)
class FieldView:
    member: str  # C++ member name
    ros_name: str
    decl: str  # member declaration without the trailing ';'
    codec: str  # the td2a::wire helper family: prim, string, msg, *_seq, *_arr
    put: str  # statement that serialises the field (without ';')
    get: str  # expression that decodes it, true on success
    size_term: str | None  # C++ expression for a variable-size field, None when fixed
    fixed_size: int  # wire size when size_term is None
    ros_type: str  # as written in the definition, for the comment


@dataclass(frozen=True)
class ConstantView:
    member: str
    decl_type: str  # C++ type of the static member
    in_class: str  # in-class declaration (with initializer for integral types)
    definition: str  # out-of-class definition (template static member)


@dataclass(frozen=True)
class MessageView:
    name: str  # canonical pkg/msg/Name
    ros1_name: str  # pkg/Name (DataType)
    package: str
    short: str
    namespace: str  # C++ namespace (package, mangled if needed)
    cls: str  # C++ class name (mangled if needed)
    qualified: str  # namespace::cls
    header: str  # include path, pkg/Type.h
    guard: str
    id_const: str
    msg_id: int
    md5: str
    definition_lines: tuple[str, ...]  # C string literals, one per definition line
    datatype_literal: str
    fields: tuple[FieldView, ...]
    constants: tuple[ConstantView, ...]
    includes: tuple[str, ...]  # headers of nested message types
    size: WireSize
    size_expr: str  # C++ expression of dataSize()
    comment: str  # the type's name for comments


def _upper_key(package: str, short: str) -> str:
    return f"{package}_{short}".upper()


def _mangle(name: str, reserved: Iterable[str], taken: set[str]) -> str:
    return mangle(name, reserved, taken, macro_like)


class TypeViews:
    """C++ views of every message a set of topics needs (the closure of their types), in first-use order."""

    def __init__(self, table: TypeTable, roots: Iterable[str], caps: Capacities, diags: Diagnostics) -> None:
        self.table = table
        self.caps = caps
        self.diags = diags
        self.order, _ = closure(table, roots)
        self._sizes: dict[str, WireSize] = {}
        self._ns: dict[str, str] = {}
        self._cls: dict[str, str] = {}
        self._name_cpp()
        keys: dict[str, str] = {}
        taken_keys: set[str] = set()
        for name in self.order:
            msg = self.table.message(name)
            keys[name] = _mangle(_upper_key(msg.package, msg.short_name), (), taken_keys)
            taken_keys.add(keys[name])
        self.views: dict[str, MessageView] = {}
        for index, name in enumerate(self.order):
            self.views[name] = self._view(self.table.message(name), keys[name], FIRST_MSG_ID + index)

    # -- closure and names -------------------------------------------------------------------------------

    def _name_cpp(self) -> None:
        namespaces: dict[str, str] = {}
        for name in self.order:
            msg = self.table.message(name)
            pkg = msg.package
            if pkg not in namespaces:
                namespaces[pkg] = _mangle(pkg, CPP_KEYWORDS | MACRO_LIKE | RESERVED_NAMESPACES, set())
                if namespaces[pkg] != pkg:
                    self.diags.warning(
                        "MROS921",
                        f"mros backend: package {pkg!r} cannot be a C++ namespace; its types live in namespace "
                        f"{namespaces[pkg]!r}",
                        hint="the ROS type names on the wire are unchanged",
                    )
            self._ns[name] = namespaces[pkg]
            cls = _mangle(msg.short_name, CPP_KEYWORDS | MACRO_LIKE | {"td2a_constants"}, set())
            if cls != msg.short_name:
                self.diags.warning(
                    "MROS921",
                    f"mros backend: message name {msg.short_name!r} ({_ros1(name)}) cannot be a C++ class name; "
                    f"the class is {cls!r}",
                    hint="the ROS type names on the wire are unchanged",
                )
            self._cls[name] = cls

    def qualified(self, name: str) -> str:
        return f"{self._ns[name]}::{self._cls[name]}"

    # -- sizes -------------------------------------------------------------------------------------------

    def _element_size(self, ftype: FieldType, string_cap: int | None = None) -> WireSize:
        if ftype.is_message:
            return self.size(ftype.base)
        if ftype.base in TIME_TYPES:
            return WireSize(8, 8, True, False)
        if ftype.base == "string":
            if ftype.string_bound:
                return WireSize(4, 4 + ftype.string_bound, False, False)
            return WireSize(4, 4 + (self.caps.string if string_cap is None else string_cap), False, True)
        width = PRIMITIVES[ftype.base][1]
        return WireSize(width, width, True, False)

    def field_size(self, ftype: FieldType, owner: str | None = None, name: str | None = None) -> WireSize:
        """Wire size of a field; `owner`/`name` pick a capacity set for this field (Capacities.fields)."""
        own = self.caps.of(owner, name)
        sequence = ftype.array is ArrayKind.SEQUENCE and not ftype.length
        elem = self._element_size(ftype, None if sequence else own)
        if ftype.array is ArrayKind.NONE:
            return elem
        if ftype.array is ArrayKind.FIXED:
            n = ftype.length
            return WireSize(elem.min * n, elem.max * n, elem.fixed, elem.unbounded)
        count = ftype.length or (self.caps.sequence if own is None else own)
        return WireSize(4, 4 + elem.max * count, False, elem.unbounded or not ftype.length)

    def size(self, name: str) -> WireSize:
        found = self._sizes.get(name)
        if found is None:
            parts = [self.field_size(f.type, name, f.name) for f in self.table.message(name).fields]
            found = WireSize(
                sum(p.min for p in parts),
                sum(p.max for p in parts),
                all(p.fixed for p in parts),
                any(p.unbounded for p in parts),
            )
            self._sizes[name] = found
        return found

    # -- C++ -----------------------------------------------------------------------------------------------

    def _cpp_element(self, ftype: FieldType) -> str:
        if ftype.is_message:
            return self.qualified(ftype.base)
        if ftype.base in TIME_TYPES:
            return TIME_TYPES[ftype.base]
        if ftype.base == "string":
            return "std::string"
        return PRIMITIVES[ftype.base][0]

    def _field(self, msg: MessageDef, index: int, member: str) -> FieldView:
        field = msg.fields[index]
        ftype = field.type
        elem = self._cpp_element(ftype)
        kind = "msg" if ftype.is_message or ftype.base in TIME_TYPES else "string" if ftype.base == "string" else "prim"
        size = self.field_size(ftype)
        elem_size = self._element_size(ftype)
        m = member
        if ftype.array is ArrayKind.NONE:
            decl = f"{elem} {m}"
            codec = kind
            put = f"td2a::wire::put_{kind}(addrPtr, {m})"
            get = f"td2a::wire::get_{kind}(p, rem, {m})"
            term = None if size.fixed else (f"{m}.dataSize()" if kind == "msg" else f"td2a::wire::size_string({m})")
        elif ftype.array is ArrayKind.FIXED:
            decl = f"{elem} {m}[{ftype.length}]"
            codec = f"{kind}_arr"
            put = f"td2a::wire::put_{codec}(addrPtr, {m})"
            get = f"td2a::wire::get_{codec}(p, rem, {m})"
            term = None if size.fixed else f"td2a::wire::size_{codec}({m})"
        else:
            decl = f"std::vector<{elem} > {m}"
            codec = f"{kind}_seq"
            put = f"td2a::wire::put_{codec}(addrPtr, {m})"
            if kind == "msg":
                get = f"td2a::wire::get_msg_seq(p, rem, {m}, {elem_size.min}u)"
                term = (
                    f"td2a::wire::size_fixed_seq({m}, {elem_size.min}u)"
                    if elem_size.fixed
                    else f"td2a::wire::size_msg_seq({m})"
                )
            else:
                get = f"td2a::wire::get_{codec}(p, rem, {m})"
                term = f"td2a::wire::size_{codec}({m})"
        return FieldView(
            member=m,
            ros_name=comment(field.name),
            decl=decl,
            codec=codec,
            put=put,
            get=get,
            size_term=term,
            fixed_size=size.min if term is None else 0,
            ros_type=comment(_ros1_field_type(ftype)),
        )

    def _constant(self, msg: MessageDef, const: Constant, member: str, cls: str) -> ConstantView | None:
        where = f"constant {const.name!r} of {_ros1(msg.name)}"
        if const.type == "string":
            value = ts.c_str(str(const.value))
            return ConstantView(
                member,
                "const char *const",
                f"static const char *const {member};",
                f"template <int D> const char *const {cls}<D>::{member} = {value};",
            )
        if const.type in ("float32", "float64"):
            number = float(const.value)
            if not math.isfinite(number):
                self.diags.warning(
                    "MROS933",
                    f"mros backend: {where} is not a finite number; it is left out of the C++ class",
                )
                return None
            ctype = PRIMITIVES[const.type][0]
            literal = repr(number) + ("f" if const.type == "float32" else "")
            return ConstantView(
                member,
                ctype,
                f"static const {ctype} {member};",
                f"template <int D> const {ctype} {cls}<D>::{member} = {literal};",
            )
        if const.type not in PRIMITIVES:
            self.diags.warning("MROS933", f"mros backend: {where} has type {const.type!r}; left out of the C++ class")
            return None
        ctype = PRIMITIVES[const.type][0]
        number_literal = _int_literal(int(const.value), const.type)
        return ConstantView(
            member,
            ctype,
            f"static const {ctype} {member} = {number_literal};",
            f"template <int D> const {ctype} {cls}<D>::{member};",
        )

    def _view(self, msg: MessageDef, key: str, msg_id: int) -> MessageView:
        cls = self._cls[msg.name]
        reserved = CPP_KEYWORDS | MACRO_LIKE | MESSAGE_MEMBERS | {cls}
        taken: set[str] = set()
        members: list[str] = []
        for f in msg.fields:
            member = _mangle(f.name, reserved, taken)
            taken.add(member)
            members.append(member)
        const_members: list[str] = []
        for c in msg.constants:
            member = _mangle(c.name, reserved, taken)
            taken.add(member)
            const_members.append(member)
        for original, member in [
            *zip([f.name for f in msg.fields], members, strict=True),
            *zip([c.name for c in msg.constants], const_members, strict=True),
        ]:
            if member != original:
                self.diags.warning(
                    "MROS920",
                    f"mros backend: {original!r} in {_ros1(msg.name)} cannot be a C++ member name; "
                    f"it is {member!r} in the generated class",
                )
        fields = tuple(self._field(msg, i, members[i]) for i in range(len(msg.fields)))
        constants = tuple(
            view
            for c, member in zip(msg.constants, const_members, strict=True)
            if (view := self._constant(msg, c, member, cls)) is not None
        )
        size = self.size(msg.name)
        fixed = sum(f.fixed_size for f in fields)
        terms = [f.size_term for f in fields if f.size_term is not None]
        if terms:
            size_expr = "(int)(" + " + ".join([*([f"{fixed}u"] if fixed else []), *terms]) + ")"
        else:
            size_expr = str(size.min)
        digest = self.table.ros1_digest(msg.name)
        text = digest.definition
        lines = text.split("\n")
        literal_lines = tuple(ts.c_str(line + "\n") for line in lines[:-1]) + (
            (ts.c_str(lines[-1]),) if lines[-1] else ()
        )
        includes = tuple(dict.fromkeys(_header(self.table, f.type.base) for f in msg.fields if f.type.is_message))
        return MessageView(
            name=msg.name,
            ros1_name=_ros1(msg.name),
            package=msg.package,
            short=msg.short_name,
            namespace=self._ns[msg.name],
            cls=cls,
            qualified=self.qualified(msg.name),
            header=_header(self.table, msg.name),
            guard=f"TD2A_MSG_{key}_H",
            id_const=f"{key}_MSG_ID",
            msg_id=msg_id,
            md5=digest.md5,
            definition_lines=literal_lines or ('""',),
            datatype_literal=ts.c_str(_ros1(msg.name)),
            fields=fields,
            constants=constants,
            includes=includes,
            size=size,
            size_expr=size_expr,
            comment=comment(_ros1(msg.name)),
        )


def _ros1(name: str) -> str:
    """`pkg/msg/Name` → `pkg/Name` (the ROS 1 spelling used on the wire)."""
    pkg, _, short = name.split("/")
    return f"{pkg}/{short}"


def _header(table: TypeTable, name: str) -> str:
    msg = table.message(name)
    return f"{msg.package}/{msg.short_name}.h"


def _ros1_field_type(ftype: FieldType) -> str:
    base = _ros1(ftype.base) if ftype.is_message else ftype.base
    if ftype.string_bound:
        base += f"<={ftype.string_bound}"
    if ftype.array is ArrayKind.FIXED:
        return f"{base}[{ftype.length}]"
    if ftype.array is ArrayKind.SEQUENCE:
        return f"{base}[<={ftype.length}]" if ftype.length else f"{base}[]"
    return base


def _int_literal(value: int, typ: str) -> str:
    """A C++98 (GNU) literal of an integer constant of ROS type `typ`, valid at its extremes."""
    if typ in ("int64",):
        return "(-9223372036854775807LL - 1)" if value == -(2**63) else f"{value}LL"
    if typ == "uint64":
        return f"{value}ULL"
    if typ == "uint32":
        return f"{value}u"
    if typ == "int32" and value == -(2**31):
        return "(-2147483647 - 1)"
    return str(value)


def closure(table: TypeTable, roots: Iterable[str]) -> tuple[list[str], list[str]]:
    """Every message the `roots` need, in the table's first-use order, and the names that do not resolve."""
    wanted: set[str] = set()
    missing: set[str] = set()
    stack = list(roots)
    while stack:
        name = stack.pop()
        if name in wanted or name in missing:
            continue
        found = table.get(name)
        if not isinstance(found, MessageDef):
            missing.add(name)
            continue
        wanted.add(name)
        stack.extend(f.type.base for f in found.fields if f.type.is_message)
    return [m.name for m in table.messages if m.name in wanted], sorted(missing)


def unsupported_fields(table: TypeTable, names: Iterable[str]) -> list[tuple[str, str, str]]:
    """(type, field, field type) of every field the mROS backend cannot represent (e.g. ROS 2 `wstring`)."""
    out = []
    for name in names:
        for f in table.message(name).fields:
            if not f.type.is_message and f.type.base not in PRIMITIVES and f.type.base not in TIME_TYPES:
                if f.type.base != "string":
                    out.append((name, f.name, str(f.type)))
    return out
