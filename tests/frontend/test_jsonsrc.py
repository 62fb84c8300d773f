"""The position-aware JSON loader: syntax errors, duplicate keys, encodings, positions of pointers."""

from __future__ import annotations

import io
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.frontend.jsonsrc import load_path, parse_json
from td2adaptor.frontend.jsonsyntax import explain


def test_positions_of_values_and_keys() -> None:
    diags = Diagnostics()
    doc = parse_json(b'{\n  "a": 1,\n  "b": [true, {"c/d": "x"}]\n}', "t.json", diags)
    assert doc is not None and not diags.items
    assert doc.position("/a") == (2, 8)
    assert doc.position("/b/1/c~1d") == (3, 23)
    assert doc.position("/b/1/c~1d", key=True) == (3, 16)
    # a pointer that does not exist falls back to its nearest existing ancestor
    assert doc.position("/b/1/missing") == (3, 15)


def test_duplicate_keys_reported_with_pointer_and_position() -> None:
    diags = Diagnostics()
    doc = parse_json(b'{"properties": {"status": {}, "x": 1,\n "status": {}}}', "d.json", diags)
    assert doc is not None
    [dup] = diags.items
    assert (dup.code, dup.severity, dup.pointer) == ("TD003", Severity.ERROR, "/properties/status")
    assert (dup.line, dup.col) == (2, 2)
    assert "status" in dup.message


def test_syntax_error_has_line_and_column() -> None:
    diags = Diagnostics()
    assert parse_json(b'{"a": 1,\n  "b": }', "s.json", diags) is None
    [d] = diags.items
    assert d.code == "TD004" and (d.line, d.col) == (2, 8) and d.file == "s.json"


def test_bom_is_tolerated_with_a_warning() -> None:
    diags = Diagnostics()
    doc = parse_json(b'\xef\xbb\xbf{"title": "x"}', "b.json", diags)
    assert doc is not None and doc.data == {"title": "x"}
    assert [d.code for d in diags] == ["TD002"] and diags.items[0].severity is Severity.WARNING


def test_invalid_utf8_is_an_error_with_position() -> None:
    diags = Diagnostics()
    assert parse_json(b'{"a":\n "caf\xe9"}', "u.json", diags) is None
    [d] = diags.items
    assert d.code == "TD001" and (d.line, d.col) == (2, 6)


def test_nan_and_infinity_are_rejected() -> None:
    for text in (b'{"a": NaN}', b'{"a": [1, -Infinity]}'):
        diags = Diagnostics()
        assert parse_json(text, "n.json", diags) is None
        assert diags.codes() == ["TD005"] and diags.items[0].line == 1


def test_unpaired_surrogate_escapes_are_errors_at_each_string() -> None:
    # a pair is one character outside the BMP and fine; a lone half cannot be written as UTF-8 by any backend
    diags = Diagnostics()
    doc = parse_json(b'{"t": "\\ud83d\\ude00", "a": "\\\\ud800"}', "ok.json", diags)
    assert doc is not None and doc.data["t"] == "\U0001f600" and not diags.items
    diags = Diagnostics()
    text = b'{"title": "x\\ud800",\n "p": {"\\uDFFFk": 1, "d": ["y\\udc00z"]}}'
    assert parse_json(text, "s.json", diags) is None
    assert diags.codes() == ["TD011"] * 3
    assert [(d.pointer, d.line) for d in diags] == [("/title", 1), ("/p/\udfffk", 2), ("/p/d/0", 2)]
    assert "member name" in diags.items[1].message and "string" in diags.items[0].message


def test_size_limit_and_deep_nesting() -> None:
    diags = Diagnostics()
    assert parse_json(b"[" * 20 + b"]" * 20, "big.json", diags, max_bytes=10) is None
    assert diags.codes() == ["TD006"]
    diags = Diagnostics()
    assert parse_json(b"[" * 100_000 + b"]" * 100_000, "deep.json", diags) is None
    assert diags.codes() == ["TD007"]


def test_stdin_and_missing_file(tmp_path: object) -> None:
    diags = Diagnostics()
    doc = load_path("-", diags, stdin=io.BytesIO(b'{"title": "from stdin"}'))
    assert doc is not None and doc.name == "<stdin>" and doc.data["title"] == "from stdin"
    assert load_path("/nonexistent/td.json", diags) is None
    assert diags.codes() == ["TD000"] and "cannot read" in diags.items[0].message


def test_root_position_without_and_with_the_source_map() -> None:
    # the root is located without mapping the whole text (a refused 100,000-affordance TD stays cheap)
    for raw in (b'\n\n   {"a": {"b\\"c": 1}}', '\ufeff {"x": 1}'.encode(), b"[1]"):
        doc = parse_json(raw, "r.json", Diagnostics())
        assert doc is not None
        quick = doc.position("")
        assert doc._map is None
        _ = doc.source_map
        assert doc.position("") == quick
    doc = parse_json(b'{"k\\"ey": {"x\\u0041": [1, {"y": 2}]}}', "e.json", Diagnostics())
    assert doc is not None and doc.position('/k"ey/xA/1/y') == (1, 33)


@pytest.mark.parametrize(
    ("text", "where", "message", "hint"),
    [
        ('{\n  "a": 1,\n  "b": {},\n}\n', (3, 10), "trailing comma before '}'", "remove this comma"),
        ('{\n  "a": [1, 2,],\n  "b": 1\n}\n', (2, 13), "trailing comma before ']'", "remove this comma"),
        ('{\n  "a": "x"\n  "b": 1\n}\n', (2, 11), "',' is missing after this value", "separate"),
        ('{\n  "a": {\n    "b": [1,\n', (3, 10), "'[' opened here is never closed", "add the missing ']'"),
        ('{\n  "a": {"x": "}"\n', (2, 8), "'{' opened here is never closed", "add the missing '}'"),
        ("{\n  'a': 1\n}\n", (2, 3), "property name", "double quotes"),
        ('{\n  /* c */ "a": 1\n}\n', (2, 3), "comments are not allowed", "remove the comment"),
    ],
)
def test_syntax_errors_point_where_they_were_made(text: str, where: tuple[int, int], message: str, hint: str) -> None:
    diags = Diagnostics()
    assert parse_json(text.encode(), "s.json", diags) is None
    [d] = diags.items
    assert d.code == "TD004" and (d.line, d.col) == where, d
    assert message in d.message and d.hint is not None and hint in d.hint


@given(st.text(alphabet="{}[],:\"\\ \n\tab1'/*", max_size=40))
def test_every_syntax_error_is_explained_inside_the_text(text: str) -> None:
    try:
        json.loads(text)
    except json.JSONDecodeError as exc:
        problem = explain(text, exc)
        assert 0 <= problem.offset <= len(text) and problem.message.startswith("invalid JSON") and problem.hint
    except RecursionError:
        pass


# JSON texts with random layout and, sometimes, a key repeated in an object (what the full map has rules for)
_keys = st.sampled_from(["a", "b", "0", "1", "a/b", "~x", 'q"', ""])
_scalars = st.sampled_from(["1", "-2.5e3", "true", "null", '"s"', '"x\\"y"'])
_space = st.sampled_from(["", " ", "\n", "\t\r\n  "])


@st.composite
def _json_texts(draw: st.DrawFn, depth: int = 0) -> str:
    kind = draw(st.sampled_from(["scalar", "object", "array"] if depth < 4 else ["scalar"]))
    if kind == "scalar":
        return draw(_scalars)
    items = []
    for _ in range(draw(st.integers(0, 4))):
        value = draw(_json_texts(depth + 1))
        items.append(f"{json.dumps(draw(_keys))}{draw(_space)}:{draw(_space)}{value}" if kind == "object" else value)
    sep = f"{draw(_space)},{draw(_space)}"
    inner = draw(_space) + sep.join(items) + draw(_space)
    return "{" + inner + "}" if kind == "object" else "[" + inner + "]"


@settings(max_examples=200, deadline=None)
@given(_json_texts(), st.lists(st.sampled_from(["a", "b", "0", "1", "2", "01", "a~1b", "~0x", 'q"', "", "-1"])))
def test_walking_to_a_pointer_finds_what_the_full_source_map_finds(text: str, extra: list[str]) -> None:
    # a diagnostic on a large TD is located without mapping every position of it (issue 17)
    from td2adaptor.frontend.jsonsrc import _FULL_MAP, SourceMap, _walk

    for lead in ("", " \n", "\ufeff"):
        doc = parse_json(lead + text, "w.json", Diagnostics())
        assert doc is not None
        full = SourceMap.build(doc.text)
        pointers = {*full.values, *full.keys, "/" + "/".join(extra), *(p + "/zz" for p in full.values)}
        for pointer in pointers:
            for key in (False, True):
                expected = full.offset(pointer, key=key)
                for unique in {False, doc.unique_keys}:
                    found = _walk(doc.text, pointer, unique_keys=unique, key=key)
                    assert found in (expected, _FULL_MAP), (pointer, key, unique)
                    assert found != _FULL_MAP or full.duplicates
        # and through the document: a few walks, then the map (the same answers)
        for key in (False, True):
            fresh = parse_json(lead + text, "w.json", Diagnostics())
            assert fresh is not None
            for pointer in sorted(pointers):
                expected = full.offset(pointer, key=key)
                assert fresh.offset(pointer, key=key) == expected
                assert fresh.position(pointer, key=key) == full.line_col(expected or 0)
