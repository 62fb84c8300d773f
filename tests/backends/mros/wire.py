"""The wire-format oracle: generated message classes against rosbags' `serialize_ros1`/`deserialize_ros1`.

A host program (built once per session) links every generated message header of an application and talks a
line protocol on stdin/stdout, so that a whole hypothesis run costs one process. Values travel as a token
walk of the fields in definition order — integers in decimal, floats as the hex of their IEEE bits, strings
as hex, sequences with their length first — built by test code from the message definitions, independently
of the generated serialisation code. Commands (`<id>`: message ID, `<hex>`: a ROS 1 serialisation):

    E <id> <tokens>   build from tokens, print `<hex of memCopy> <dataSize()>`
    D <id> <hex>      bounded decode (td2a_read): `ok <bytes left> <tokens>` or `fail`
    U <id> <hex>      the contract's deserialize(char *&): `<bytes consumed> <tokens>`
    C <id> <hex>      mROS's subscription path (CallCallbackFuncs with the length prefix): `cb <tokens>` or `dropped`
    S <id> <tokens>   swap with a default-constructed message: `<hex of the other> <hex of the first>`
    T <id>            traits: `<md5> <datatype> <hex of definition> <DataTypeId>`
    Z <id>            a default-constructed message: `<hex>`
"""

from __future__ import annotations

import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

from td2adaptor.backends.mros.types import PRIMITIVES, MessageView, TypeViews
from td2adaptor.model import ArrayKind, FieldType, TypeTable

INT_RANGES = {
    "bool": (0, 1),
    "byte": (-(2**7), 2**7 - 1),
    "char": (0, 2**8 - 1),
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
DTYPES = {
    "bool": np.bool_,
    "byte": np.int8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}
#: rosbags' ROS 1 time/duration are builtin_interfaces messages with sec/nanosec (nanosec unsigned), so the
#: values stay where both readings agree
TIME_RANGES = {"time": ((0, 2**31 - 1), (0, 2**32 - 1)), "duration": ((-(2**31), 2**31 - 1), (0, 2**31 - 1))}
TIME_TYPES = {"time": "builtin_interfaces/msg/Time", "duration": "builtin_interfaces/msg/Duration"}


# ---------------------------------------------------------------------------------------------------------
# values: hypothesis strategies, tokens, rosbags objects


def _scalar(ftype: FieldType, table: TypeTable, caps: tuple[int, int], size: str) -> st.SearchStrategy[Any]:
    base = ftype.base
    if ftype.is_message:
        return message_values(table, base, caps, size)
    if base in TIME_RANGES:
        (s0, s1), (n0, n1) = TIME_RANGES[base]
        if size == "max":
            return st.just((s1, n1))
        if size == "empty":
            return st.just((0, 0))
        return st.tuples(st.integers(s0, s1), st.integers(n0, n1))
    if base == "string":
        if size == "max":
            return st.just("x" * caps[0])
        if size == "empty":
            return st.just("")
        return st.text(max_size=caps[0] // 2) | st.text('abc"\\\n\x00', max_size=caps[0])
    if base == "float32":
        return st.just(0.0) if size == "empty" else st.floats(width=32, allow_nan=False)
    if base == "float64":
        return st.just(0.0) if size == "empty" else st.floats(allow_nan=False)
    lo, hi = INT_RANGES[base]
    if size == "max":
        return st.just(hi)
    if size == "empty":
        return st.just(0)
    return st.integers(lo, hi)


def field_values(ftype: FieldType, table: TypeTable, caps: tuple[int, int], size: str) -> st.SearchStrategy[Any]:
    elem = _scalar(ftype, table, caps, size)
    if ftype.array is ArrayKind.NONE:
        return elem
    if ftype.array is ArrayKind.FIXED:
        return st.lists(elem, min_size=ftype.length, max_size=ftype.length)
    bound = ftype.length or caps[1]
    if size == "max":
        return st.lists(elem, min_size=bound, max_size=bound)
    if size == "empty":
        return st.just([])
    return st.lists(elem, max_size=bound + (0 if ftype.length else 2))


def message_values(table: TypeTable, name: str, caps: tuple[int, int], size: str = "any") -> st.SearchStrategy[Any]:
    """Field values of message `name` in definition order (a list). `size`: any, empty or max (every string
    and unbounded sequence at its assumed capacity)."""
    msg = table.message(name)
    return st.tuples(*(field_values(f.type, table, caps, size) for f in msg.fields)).map(list)


def fixed_value(table: TypeTable, name: str, caps: tuple[int, int], size: str) -> list[Any]:
    """A deterministic value: `empty` (zeros, empty strings and sequences, as a default-constructed message)
    or `max` (largest integers, every string and unbounded sequence at its assumed capacity)."""
    return [_fixed_field(table, f.type, caps, size) for f in table.message(name).fields]


def _fixed_field(table: TypeTable, ftype: FieldType, caps: tuple[int, int], size: str) -> Any:
    def one() -> Any:
        if ftype.is_message:
            return fixed_value(table, ftype.base, caps, size)
        if ftype.base in TIME_RANGES:
            (_, s1), (_, n1) = TIME_RANGES[ftype.base]
            return (s1, n1) if size == "max" else (0, 0)
        if ftype.base == "string":
            return "x" * (ftype.string_bound or caps[0]) if size == "max" else ""
        if ftype.base in ("float32", "float64"):
            return -1.5 if size == "max" else 0.0
        return INT_RANGES[ftype.base][1] if size == "max" else 0

    if ftype.array is ArrayKind.NONE:
        return one()
    if ftype.array is ArrayKind.FIXED:
        return [one() for _ in range(ftype.length)]
    count = (ftype.length or caps[1]) if size == "max" else 0
    return [one() for _ in range(count)]


def _float_token(base: str, value: float) -> str:
    if base == "float32":
        return "f" + struct.pack("<f", value).hex()
    return "d" + struct.pack("<d", value).hex()


def tokens(table: TypeTable, name: str, value: list[Any]) -> list[str]:
    out: list[str] = []
    for f, v in zip(table.message(name).fields, value, strict=True):
        _field_tokens(table, f.type, v, out)
    return out


def _field_tokens(table: TypeTable, ftype: FieldType, value: Any, out: list[str]) -> None:
    items = [value] if ftype.array is ArrayKind.NONE else value
    if ftype.array is ArrayKind.SEQUENCE:
        out.append(f"n{len(items)}")
    for v in items:
        if ftype.is_message:
            out.extend(tokens(table, ftype.base, v))
        elif ftype.base in TIME_RANGES:
            out.extend([str(v[0]), str(v[1])])
        elif ftype.base == "string":
            out.append("s" + v.encode("utf-8").hex())
        elif ftype.base in ("float32", "float64"):
            out.append(_float_token(ftype.base, v))
        else:
            out.append(str(int(v)))


def to_rosbags(ts: Any, table: TypeTable, name: str, value: list[Any]) -> Any:
    """The rosbags message object of a value."""
    msg = table.message(name)
    kwargs = {f.name: _rosbags_field(ts, table, f.type, v) for f, v in zip(msg.fields, value, strict=True)}
    if not msg.fields:
        return ts.types[name]()
    return ts.types[name](**kwargs)


def _rosbags_field(ts: Any, table: TypeTable, ftype: FieldType, value: Any) -> Any:
    def one(v: Any) -> Any:
        if ftype.is_message:
            return to_rosbags(ts, table, ftype.base, v)
        if ftype.base in TIME_TYPES:
            return ts.types[TIME_TYPES[ftype.base]](sec=v[0], nanosec=v[1])
        if ftype.base == "bool":
            return bool(v)
        return v

    if ftype.array is ArrayKind.NONE:
        return one(value)
    if ftype.is_message or ftype.base in TIME_TYPES or ftype.base == "string":
        return [one(v) for v in value]
    arr: Any = np.array(value, dtype=DTYPES[ftype.base])
    return arr.view(np.uint8) if ftype.base == "byte" else arr


# ---------------------------------------------------------------------------------------------------------
# the C++ side


_READERS = """
struct Tok {
    std::istringstream in;
    std::string next() { std::string t; in >> t; return t; }
};
struct Out {  // a global type, so that argument-dependent lookup finds the wr overloads of message types
    std::ostringstream s;
};
template <class T> static void rd_int(Tok &t, T &v) { v = (T)std::stoll(t.next()); }
static void rd(Tok &t, uint64_t &v) { v = std::stoull(t.next()); }
static void rd(Tok &t, int64_t &v) { v = std::stoll(t.next()); }
static void rd(Tok &t, uint32_t &v) { rd_int(t, v); }
static void rd(Tok &t, int32_t &v) { rd_int(t, v); }
static void rd(Tok &t, uint16_t &v) { rd_int(t, v); }
static void rd(Tok &t, int16_t &v) { rd_int(t, v); }
static void rd(Tok &t, uint8_t &v) { rd_int(t, v); }
static void rd(Tok &t, int8_t &v) { rd_int(t, v); }
static std::string unhex(const std::string &h) {
    std::string out;
    for (size_t i = 0; i + 1 < h.size(); i += 2) out += (char)std::stoi(h.substr(i, 2), nullptr, 16);
    return out;
}
static std::string hex(const std::string &b) {
    static const char *d = "0123456789abcdef";
    std::string out;
    for (unsigned char c : b) { out += d[c >> 4]; out += d[c & 15]; }
    return out;
}
static void rd(Tok &t, float &v) { std::string b = unhex(t.next().substr(1)); memcpy(&v, b.data(), 4); }
static void rd(Tok &t, double &v) { std::string b = unhex(t.next().substr(1)); memcpy(&v, b.data(), 8); }
static void rd(Tok &t, std::string &v) { v = unhex(t.next().substr(1)); }
static void rd(Tok &t, td2a::Time &v) { rd(t, v.sec); rd(t, v.nsec); }
static void rd(Tok &t, td2a::Duration &v) { rd(t, v.sec); rd(t, v.nsec); }
template <class T> static void rd(Tok &t, std::vector<T> &v) {
    v.resize(std::stoul(t.next().substr(1)));
    for (auto &e : v) rd(t, e);
}
template <class T, size_t N> static void rd(Tok &t, T (&a)[N]) { for (auto &e : a) rd(t, e); }

static void wr(Out &o, uint64_t v) { o.s << ' ' << v; }
static void wr(Out &o, int64_t v) { o.s << ' ' << v; }
static void wr(Out &o, uint32_t v) { o.s << ' ' << v; }
static void wr(Out &o, int32_t v) { o.s << ' ' << v; }
static void wr(Out &o, uint16_t v) { o.s << ' ' << v; }
static void wr(Out &o, int16_t v) { o.s << ' ' << v; }
static void wr(Out &o, uint8_t v) { o.s << ' ' << (int)v; }
static void wr(Out &o, int8_t v) { o.s << ' ' << (int)v; }
static void wr(Out &o, float v) { std::string b(4, 0); memcpy(&b[0], &v, 4); o.s << " f" << hex(b); }
static void wr(Out &o, double v) { std::string b(8, 0); memcpy(&b[0], &v, 8); o.s << " d" << hex(b); }
static void wr(Out &o, const std::string &v) { o.s << " s" << hex(v); }
static void wr(Out &o, const td2a::Time &v) { wr(o, v.sec); wr(o, v.nsec); }
static void wr(Out &o, const td2a::Duration &v) { wr(o, v.sec); wr(o, v.nsec); }
template <class T> static void wr(Out &o, const std::vector<T> &v) {
    o.s << " n" << v.size();
    for (const auto &e : v) wr(o, e);
}
template <class T, size_t N> static void wr(Out &o, const T (&a)[N]) { for (const auto &e : a) wr(o, e); }
"""

_MAIN = """
template <class M> static std::string encode(const M &m) {
    // as mROS's publish: the body goes after the 4-byte length word, which memCopy fills in itself
    std::string buf(4 + (size_t)m.dataSize() + 8, '\\x5a');
    char *p = &buf[4];
    m.memCopy(p);
    if (p != &buf[4] + m.dataSize()) return "SIZE-MISMATCH";
    if (buf.substr(4 + (size_t)m.dataSize()) != std::string(8, '\\x5a')) return "OVERRUN";
    uint32_t len = 0;
    memcpy(&len, &buf[0], 4);
    if (len != (uint32_t)m.dataSize()) return "BAD-LENGTH-WORD";
    return hex(buf.substr(4, (size_t)m.dataSize()));
}
static Out *g_out;
static bool g_called;
template <class M> static void callback(void *msg) { g_called = true; wr(*g_out, *static_cast<M *>(msg)); }

template <class M, int ID> static void run(char cmd, Tok &t, Out &o) {
    std::ostringstream &out = o.s;
    if (cmd == 'E') {
        M m; rd(t, m);
        out << encode(m) << ' ' << m.dataSize();
    } else if (cmd == 'Z') {
        M m; out << encode(m);
    } else if (cmd == 'S') {
        M a, b; rd(t, a); a.swap(b);
        out << encode(a) << ' ' << encode(b);
    } else if (cmd == 'D') {
        std::string bytes = unhex(t.next());
        std::vector<char> buf(bytes.begin(), bytes.end()); buf.push_back(0);
        char *p = &buf[0]; uint32_t rem = (uint32_t)bytes.size();
        M m;
        if (m.td2a_read(p, rem)) { out << "ok " << rem; wr(o, m); } else { out << "fail"; }
    } else if (cmd == 'U') {
        std::string bytes = unhex(t.next());
        std::vector<char> buf(bytes.begin(), bytes.end()); buf.push_back(0);
        char *p = &buf[0];
        M m; m.deserialize(p);
        out << (p - &buf[0]); wr(o, m);
    } else if (cmd == 'C') {
        std::string bytes = unhex(t.next());
        uint32_t n = (uint32_t)bytes.size();
        std::string block(4, 0); memcpy(&block[0], &n, 4); block += bytes;
        std::vector<char> buf(block.begin(), block.end()); buf.push_back(0);
        Out got; g_out = &got; g_called = false;
        subtask_methods::CallCallbackFuncs<ID>::call(&callback<M>, &buf[0]);
        out << (g_called ? "cb" : "dropped") << got.s.str();
    } else if (cmd == 'T') {
        out << message_traits::MD5Sum<ID>::value() << ' ' << message_traits::DataType<M *>::value() << ' '
            << hex(message_traits::Definition<M *>::value()) << ' ' << message_traits::DataTypeId<M *>::value();
    }
}

int main() {
    std::string line;
    while (std::getline(std::cin, line)) {
        Tok t; t.in.str(line);
        std::string cmd = t.next();
        int id = std::stoi(t.next());
        Out o;
        std::ostringstream &out = o.s;
        switch (id) {
@CASES@
        default: out << "unknown id";
        }
        std::cout << out.str() << '\\n' << std::flush;
    }
}
"""


def harness_source(views: TypeViews) -> str:
    """The C++17 host program for every message of `views` (the application's headers must be on the path)."""
    lines = ["/* td2adaptor test harness: wire-format oracle for generated mROS message headers. */"]
    lines += ["#include <cstring>", "#include <iostream>", "#include <sstream>", "#include <string>"]
    msgs = [views.views[n] for n in views.order]
    lines += [f'#include "{m.header}"' for m in msgs]
    lines.append(_READERS)
    for m in msgs:
        lines.append(f"static void rd(Tok &t, {m.qualified} &m);")
        lines.append(f"static void wr(Out &o, const {m.qualified} &m);")
    for m in msgs:
        body = " ".join(f"rd(t, m.{f.member});" for f in m.fields)
        lines.append(f"static void rd(Tok &t, {m.qualified} &m) {{ (void)t; (void)m; {body} }}")
        body = " ".join(f"wr(o, m.{f.member});" for f in m.fields)
        lines.append(f"static void wr(Out &o, const {m.qualified} &m) {{ (void)o; (void)m; {body} }}")
    cases = "\n".join(f"        case {m.msg_id}: run<{m.qualified}, {m.id_const}>(cmd[0], t, o); break;" for m in msgs)
    lines.append(_MAIN.replace("@CASES@", cases))
    return "\n".join(lines) + "\n"


@dataclass
class Harness:
    """A running harness process: one request line, one reply line."""

    proc: subprocess.Popen[str]

    @classmethod
    def start(cls, exe: Path) -> Harness:
        proc = subprocess.Popen([str(exe)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        return cls(proc)

    def ask(self, line: str) -> str:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()
        reply = self.proc.stdout.readline()
        assert reply, f"harness died on: {line[:200]}"
        return reply.rstrip("\n")

    def close(self) -> None:
        for stream in (self.proc.stdin, self.proc.stdout):
            if stream is not None:
                stream.close()
        self.proc.wait(timeout=30)


def message_view(views: TypeViews, name: str) -> MessageView:
    return views.views[name]


def width(base: str) -> int:
    return PRIMITIVES[base][1]
