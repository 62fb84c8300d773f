"""JSON documents that remember where every value came from.

Parsing uses the C `json` module (fast, strict); positions are computed lazily, only when a diagnostic needs a
`line:col`, so valid input pays nothing for them. A few positions are found by walking the text along the
pointer (`_walk`: the C decoder skips every value off the path); many, by mapping every position once
(`SourceMap`, a small scanner that also finds the duplicate keys `json.loads` silently collapses).
"""

from __future__ import annotations

import bisect
import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from json.scanner import make_scanner
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, pointer_join

#: Limits that keep time and memory bounded on hostile input; all configurable (CLI --max-bytes).
DEFAULT_MAX_BYTES = 16 * 1024 * 1024
DEFAULT_MAX_DEPTH = 100

_WS = re.compile(r"[ \t\n\r]*")
_STR = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)
_SCALAR = re.compile(r"[^\s,\]}:]+")
# `\ud800`-style escapes that may decode to a lone surrogate (a valid pair decodes to one character)
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")
_SURROGATE = re.compile("[\ud800-\udfff]")


@dataclass
class SourceMap:
    """Pointer → character offset of values and keys, plus duplicate keys, for one JSON text."""

    values: dict[str, int]
    keys: dict[str, int]
    duplicates: list[tuple[str, str, int]]  # (object pointer, key, offset of the repeated key)
    _newlines: list[int]

    @classmethod
    def build(cls, text: str) -> SourceMap:
        values, keys, dups = _scan(text)
        newlines = [m.start() for m in re.finditer("\n", text)]
        return cls(values, keys, dups, newlines)

    def line_col(self, offset: int) -> tuple[int, int]:
        line = bisect.bisect_left(self._newlines, offset)
        start = self._newlines[line - 1] + 1 if line else 0
        return line + 1, offset - start + 1

    def offset(self, pointer: str, *, key: bool = False) -> int | None:
        """Offset of the value (or its key) at `pointer`, else of the nearest existing ancestor."""
        if key and pointer in self.keys:
            return self.keys[pointer]
        ptr = pointer
        while True:
            if ptr in self.values:
                return self.values[ptr]
            if not ptr:
                return None
            ptr = ptr.rsplit("/", 1)[0]


@dataclass
class _Frame:
    """An open object or array while scanning."""

    is_object: bool
    pointer: str
    index: int = 0
    seen: set[str] = field(default_factory=set)


def _scan(text: str) -> tuple[dict[str, int], dict[str, int], list[tuple[str, str, int]]]:
    """Walk a JSON text already accepted by `json.loads`, recording where each value and key starts."""
    values: dict[str, int] = {}
    keys: dict[str, int] = {}
    dups: list[tuple[str, str, int]] = []
    stack: list[_Frame] = []
    i = _WS.match(text, 1 if text.startswith("\ufeff") else 0).end()  # type: ignore[union-attr]
    pointer = ""

    def read_key(frame: _Frame, i: int) -> tuple[str, int]:
        m = _STR.match(text, i)
        assert m is not None
        raw = m.group()
        name = json.loads(raw) if "\\" in raw else raw[1:-1]  # only escapes need decoding
        ptr = pointer_join(frame.pointer, name)
        if name in frame.seen:
            dups.append((frame.pointer, name, i))
        else:
            frame.seen.add(name)
            keys[ptr] = i
        i = _WS.match(text, m.end()).end()  # type: ignore[union-attr]
        return ptr, _WS.match(text, i + 1).end()  # type: ignore[union-attr]  # skip ':'

    while True:
        values.setdefault(pointer, i)
        c = text[i]
        if c in "{[":
            is_obj = c == "{"
            i = _WS.match(text, i + 1).end()  # type: ignore[union-attr]
            if text[i] in "}]":
                i = _WS.match(text, i + 1).end()  # type: ignore[union-attr]
            else:
                frame = _Frame(is_obj, pointer)
                stack.append(frame)
                if is_obj:
                    pointer, i = read_key(frame, i)
                else:
                    pointer = pointer_join(frame.pointer, 0)
                continue
        else:
            m = (_STR if c == '"' else _SCALAR).match(text, i)
            assert m is not None
            i = _WS.match(text, m.end()).end()  # type: ignore[union-attr]
        # a value ended at i: close containers until the next sibling
        while stack:
            frame = stack[-1]
            if i < len(text) and text[i] == ",":
                i = _WS.match(text, i + 1).end()  # type: ignore[union-attr]
                if frame.is_object:
                    pointer, i = read_key(frame, i)
                else:
                    frame.index += 1
                    pointer = pointer_join(frame.pointer, frame.index)
                break
            stack.pop()
            i = _WS.match(text, i + 1).end()  # type: ignore[union-attr]
        else:
            return values, keys, dups


# the C decoder's pieces: a value's end, a key's text (both typed here: the stubs do not say)
_scan_once: Callable[[str, int], tuple[Any, int]] = make_scanner(json.JSONDecoder())  # type: ignore[arg-type]
_scanstring: Callable[[str, int], tuple[str, int]] = json.decoder.scanstring  # type: ignore[attr-defined]
_FULL_MAP = -2  # `_walk`: this pointer needs the full source map


def _escape(name: str) -> str:
    return name.replace("~", "~0").replace("/", "~1")


def _walk(text: str, pointer: str, *, unique_keys: bool, key: bool) -> int | None:
    """`SourceMap.build(text).offset(pointer, key=key)` without mapping the whole text.

    Descends along `pointer`, skipping each value off the path with the C decoder. The full map records the
    first occurrence of a value (and the last object's occurrence of a key) when a key is repeated; rather
    than copy that rule, a key repeated on the path answers `_FULL_MAP`. Unless `unique_keys` (the parser
    found no duplicate anywhere), that means reading every member of each object on the path.
    """
    if pointer and not pointer.startswith("/"):
        return _FULL_MAP
    scan_once, scanstring = _scan_once, _scanstring
    ws = _WS.match
    i = ws(text, 1 if text.startswith("\ufeff") else 0).end()  # type: ignore[union-attr]
    key_at: int | None = None
    try:
        for token in pointer.split("/")[1:]:
            c = text[i]
            if c == "{":
                found: tuple[int, int] | None = None
                j = ws(text, i + 1).end()  # type: ignore[union-attr]
                while text[j] != "}":
                    name, end = scanstring(text, j + 1)
                    at = j
                    j = ws(text, ws(text, end).end() + 1).end()  # type: ignore[union-attr]  # past ':'
                    if _escape(name) == token:
                        if found is not None:
                            return _FULL_MAP
                        found = (at, j)
                        if unique_keys:
                            break
                    j = ws(text, scan_once(text, j)[1]).end()  # type: ignore[union-attr]
                    if text[j] == ",":
                        j = ws(text, j + 1).end()  # type: ignore[union-attr]
                    else:
                        break
                if found is None:
                    return i
                key_at, i = found
            elif c == "[":
                if not (token.isascii() and token.isdigit() and str(int(token)) == token):
                    return i
                j = ws(text, i + 1).end()  # type: ignore[union-attr]
                if text[j] == "]":
                    return i
                for _ in range(int(token)):
                    j = ws(text, scan_once(text, j)[1]).end()  # type: ignore[union-attr]
                    if text[j] != ",":
                        return i
                    j = ws(text, j + 1).end()  # type: ignore[union-attr]
                key_at, i = None, j
            else:
                return i
    except (IndexError, ValueError, StopIteration):  # not a JSON text after all: the full map's answer
        return _FULL_MAP
    return key_at if key and key_at is not None else i


#: Positions found by walking the text before the document maps it whole (a walk reads up to all of it).
_WALKS = 8


@dataclass
class JsonDocument:
    """A parsed JSON document with its text, for positions, and its path, for relative references."""

    name: str
    text: str
    data: Any
    path: Path | None = None
    _map: SourceMap | None = field(default=None, repr=False)
    #: The parser found no key repeated in an object of `text` (set by `parse_json`).
    unique_keys: bool = field(default=False, repr=False)
    _walks: int = field(default=0, repr=False)

    @property
    def source_map(self) -> SourceMap:
        if self._map is None:
            self._map = SourceMap.build(self.text)
        return self._map

    def offset(self, pointer: str, *, key: bool = False) -> int | None:
        """Character offset of the value (or its key) at `pointer`, else of its nearest existing ancestor."""
        if self._map is None and self._walks < _WALKS:
            self._walks += 1
            off = _walk(self.text, pointer, unique_keys=self.unique_keys, key=key)
            if off != _FULL_MAP:
                return off
        return self.source_map.offset(pointer, key=key)

    def position(self, pointer: str, *, key: bool = False) -> tuple[int, int] | None:
        if not pointer and self._map is None:  # the whole document: no need to map a large text for it
            start = 1 if self.text.startswith("\ufeff") else 0
            return doc_line_col(self.text, _WS.match(self.text, start).end())  # type: ignore[union-attr]
        off = self.offset(pointer, key=key)
        if off is None:
            return None
        return self._map.line_col(off) if self._map is not None else doc_line_col(self.text, off)

    def locate(self, diag: Diagnostic) -> Diagnostic:
        """Attach this document's file name and the line:col of the diagnostic's pointer."""
        if diag.line is not None:
            return diag if diag.file else replace(diag, file=self.name)
        pos = self.position(diag.pointer, key=diag.code in _KEY_CODES)
        if pos is None:
            return replace(diag, file=diag.file or self.name)
        return replace(diag, file=diag.file or self.name, line=pos[0], col=pos[1])


# diagnostics about a key itself (unknown term, duplicate) point at the key, not its value
_KEY_CODES = {"TD003", "TD201", "TD202", "TD203", "XC601", "XC603"}


class _Duplicates(Exception):
    pass


def _pairs_hook(flag: list[bool]) -> Any:
    def hook(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        d = dict(pairs)
        if len(d) != len(pairs):
            flag[0] = True
        return d

    return hook


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not valid JSON")


#: When a list, every file parsed appends (resolved path, sha256 of its bytes): the result cache's dependencies.
READ_LOG: list[tuple[str, str]] | None = None


def parse_json(
    raw: bytes | str,
    name: str,
    diags: Diagnostics,
    *,
    path: Path | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    max_depth: int = DEFAULT_MAX_DEPTH,
) -> JsonDocument | None:
    """Decode and parse `raw`; report encoding, syntax and duplicate-key problems into `diags`.

    Returns None when the text cannot be parsed at all (an error has then been reported).
    """
    if READ_LOG is not None and path is not None:
        import hashlib

        data = raw if isinstance(raw, bytes) else raw.encode("utf-8")
        READ_LOG.append((str(path), hashlib.sha256(data).hexdigest()))
    size = len(raw)
    if size > max_bytes:
        diags.add(
            "TD006",
            Severity.ERROR,
            f"input is {size} bytes, more than the limit of {max_bytes} bytes",
            hint="raise the limit with --max-bytes if this document is really that large",
            file=name,
        )
        return None
    if isinstance(raw, bytes):
        if raw.startswith(b"\xef\xbb\xbf"):
            diags.add(
                "TD002",
                Severity.WARNING,
                "input starts with a UTF-8 byte order mark",
                "",
                "remove the BOM",
                file=name,
            )
            raw = raw[3:]
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            before = raw[: exc.start]
            line = before.count(b"\n") + 1
            col = len(before[before.rfind(b"\n") + 1 :].decode("utf-8", "replace")) + 1
            diags.append(
                Diagnostic(
                    "TD001",
                    Severity.ERROR,
                    f"input is not valid UTF-8: byte 0x{raw[exc.start]:02x} at offset {exc.start}",
                    "",
                    "Thing Descriptions must be encoded in UTF-8",
                    name,
                    line,
                    col,
                )
            )
            return None
    else:
        text = raw
        if text.startswith("\ufeff"):
            diags.add(
                "TD002",
                Severity.WARNING,
                "input starts with a byte order mark",
                "",
                "remove the BOM",
                file=name,
            )
            text = text[1:]
    flag = [False]
    try:
        data = json.loads(text, object_pairs_hook=_pairs_hook(flag), parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        from td2adaptor.frontend.jsonsyntax import explain

        problem = explain(text, exc)
        line, col = doc_line_col(text, problem.offset)
        diags.append(Diagnostic("TD004", Severity.ERROR, problem.message, "", problem.hint, name, line, col))
        return None
    except ValueError as exc:  # NaN / Infinity
        off = _find_constant(text)
        where = (None, None) if off is None else doc_line_col(text, off)
        diags.append(
            Diagnostic(
                "TD005",
                Severity.ERROR,
                f"invalid JSON: {exc}",
                "",
                "use null or a finite number",
                name,
                *where,
            )
        )
        return None
    except RecursionError:
        diags.add("TD007", Severity.ERROR, "JSON nesting is too deep to process", "", None, file=name)
        return None
    deepest = _depth_over(data, max_depth)
    if deepest:
        diags.add(
            "TD007",
            Severity.ERROR,
            f"JSON nesting deeper than {max_depth} levels at {deepest}",
            hint="Thing Descriptions are rarely deeper than 30 levels; check the input",
            file=name,
        )
        return None
    doc = JsonDocument(name, text, data, path, unique_keys=not flag[0])
    if _SURROGATE_ESCAPE.search(text) and (bad := _lone_surrogates(data)):
        for ptr, is_key in bad:
            what = "a member name" if is_key else "a string"
            diags.append(
                doc.locate(
                    Diagnostic(
                        "TD011",
                        Severity.ERROR,
                        f"{what} contains an unpaired surrogate escape (\\ud800-\\udfff), which is not Unicode text",
                        ptr,
                        "escape characters outside the BMP as a surrogate pair, or write them as UTF-8",
                        name,
                    )
                )
            )
        return None
    if flag[0]:
        for obj_ptr, key, off in doc.source_map.duplicates:
            line, col = doc.source_map.line_col(off)
            diags.append(
                Diagnostic(
                    "TD003",
                    Severity.ERROR,
                    f"duplicate key {key!r}: JSON parsers silently keep only the last one",
                    pointer_join(obj_ptr, key),
                    "give every member of an object a unique name",
                    name,
                    line,
                    col,
                )
            )
    return doc


def _depth_over(data: Any, limit: int) -> str | None:
    """The JSON pointer of a value nested deeper than `limit`, else None (iterative: no recursion limit)."""
    stack: list[tuple[Any, int, str]] = [(data, 1, "")]
    while stack:
        value, depth, ptr = stack.pop()
        if depth > limit:
            return ptr or "/"
        if isinstance(value, dict):
            stack.extend((v, depth + 1, pointer_join(ptr, k)) for k, v in value.items() if isinstance(v, (dict, list)))
        elif isinstance(value, list):
            stack.extend(
                (v, depth + 1, pointer_join(ptr, i)) for i, v in enumerate(value) if isinstance(v, (dict, list))
            )
    return None


def _lone_surrogates(data: Any) -> list[tuple[str, bool]]:
    """(pointer, is a key) of every string holding a lone surrogate, in document order (iterative)."""
    found: list[tuple[str, bool]] = []
    stack: list[tuple[Any, str]] = [(data, "")]
    while stack:
        value, ptr = stack.pop()
        if isinstance(value, str):
            if _SURROGATE.search(value):
                found.append((ptr, False))
        elif isinstance(value, dict):
            for k in value:
                if _SURROGATE.search(k):
                    found.append((pointer_join(ptr, k), True))
            stack.extend((v, pointer_join(ptr, k)) for k, v in reversed(value.items()))
        elif isinstance(value, list):
            stack.extend((v, pointer_join(ptr, i)) for i, v in reversed(list(enumerate(value))))
    return found


def doc_line_col(text: str, offset: int) -> tuple[int, int]:
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def _find_constant(text: str) -> int | None:
    m = re.search(r"(?<![\w\"])(-?Infinity|NaN)(?![\w\"])", text)
    return m.start() if m else None


#: Documents parsed only to see what they are (`load_path(keep=True)`), each taken by the next load of the same
#: bytes under the same name and limit instead of parsing them again: (name, limit) → (bytes, document, its
#: parse diagnostics). A few at most, each taken once.
_KEPT: dict[tuple[str, int], tuple[bytes, JsonDocument | None, list[Diagnostic]]] = {}
_KEEP_AT_MOST = 8


def load_path(
    source: str, diags: Diagnostics, *, stdin: Any = None, max_bytes: int = DEFAULT_MAX_BYTES, keep: bool = False
) -> JsonDocument | None:
    """Read a path or `-` (stdin) and parse it. With `keep`, the next load of the file takes this parse (when
    its bytes are still the same): a file read to decide how to compile it is parsed once."""
    import sys

    if source == "-":
        stream = stdin if stdin is not None else sys.stdin.buffer
        raw = stream.read(max_bytes + 1)
        return parse_json(raw, "<stdin>", diags, path=None, max_bytes=max_bytes)
    p = Path(source)
    try:
        with p.open("rb") as fh:
            raw = fh.read(max_bytes + 1)
    except OSError as exc:
        diags.add("TD000", Severity.ERROR, f"cannot read {source}: {exc.strerror or exc}", file=source)
        return None
    kept = _KEPT.pop((source, max_bytes), None)
    if kept is not None and kept[0] == raw:
        if READ_LOG is not None:
            import hashlib

            READ_LOG.append((str(p.resolve()), hashlib.sha256(raw).hexdigest()))
        diags.extend(kept[2])
        return kept[1]
    if not keep:
        return parse_json(raw, source, diags, path=p.resolve(), max_bytes=max_bytes)
    found = Diagnostics()
    doc = parse_json(raw, source, found, path=p.resolve(), max_bytes=max_bytes)
    diags.extend(found)
    _KEPT[(source, max_bytes)] = (raw, doc, list(found))
    while len(_KEPT) > _KEEP_AT_MOST:
        del _KEPT[next(iter(_KEPT))]
    return doc
