"""Safe literals: no text can close the literal or comment it is put in."""

from __future__ import annotations

import ast

from hypothesis import given
from hypothesis import strategies as st

from td2adaptor.generation.textsafe import c_comment, c_str, md_inline, py_docstring, py_str, xml_text

nasty = st.text(alphabet=st.sampled_from(list("\"'\\*/?\n\r\x00<>&#{}%\u2028 abc")), max_size=30)


@given(nasty)
def test_python_literals_round_trip(text: str) -> None:
    module = ast.parse(f"def f():\n    {py_docstring(text)}\n\nx = {py_str(text)}\n")
    assert [type(n).__name__ for n in module.body] == ["FunctionDef", "Assign"]
    assert ast.literal_eval(py_str(text)) == text


@given(nasty)
def test_c_comment_cannot_close_or_continue(text: str) -> None:
    out = c_comment(text)
    assert "*/" not in out and "/*" not in out and "??" not in out and "\\" not in out and "\n" not in out


def test_c_comment_known_traps() -> None:
    assert c_comment("a*\\b") == "a* /b"  # backslash first: `*\` must not become `*/`
    assert "??" not in c_comment("??/ line continuation")


@given(nasty)
def test_c_string_is_one_literal(text: str) -> None:
    out = c_str(text)
    assert out.startswith('"') and out.endswith('"')
    body = out[1:-1]
    assert "??" not in body and "\n" not in body
    i = 0
    while i < len(body):  # every quote or backslash is escaped
        if body[i] == "\\":
            i += 2
            continue
        assert body[i] != '"'
        i += 1


@given(nasty)
def test_xml_text_has_no_markup(text: str) -> None:
    out = xml_text(text)
    assert "<" not in out and ">" not in out and '"' not in out
    assert "&" not in out.replace("&amp;", "").replace("&lt;", "").replace("&gt;", "").replace("&quot;", "")


@given(nasty)
def test_md_inline_is_one_line_of_plain_text(text: str) -> None:
    out = md_inline(text)
    assert "\n" not in out and "\r" not in out and "\u2028" not in out and "\x00" not in out
    unescaped = out.replace("\\\\", "")  # every special character left is preceded by a backslash
    for ch in "`*_[]<>|#":
        assert ch not in unescaped.replace("\\" + ch, "")
    assert out.replace("\\", "") == " ".join(text.replace("\x00", " ").split()).replace("\\", "")


@given(st.text(alphabet=st.sampled_from('ab "\\\u00e9\u4e2d\n\t\x01'), max_size=200), st.integers(4, 30))
def test_wrap_lines_keeps_every_word_within_the_width(text: str, width: int) -> None:
    from td2adaptor.generation.textsafe import _BREAKS, _JUNK, wrap_lines

    lines = wrap_lines(text, width)
    for line in lines:
        wide = line.count("\u00e9") + line.count("\u4e2d")  # counted two columns, to be safe
        assert len(py_docstring(line)) - len('""""""') + wide <= width and line == line.strip()
    # nothing lost or reordered: the same characters, only spaces and line breaks moved
    squeeze = "".join(_JUNK.sub(" ", "".join(_BREAKS.split(text))).split())
    assert "".join("".join(lines).split()) == squeeze
    assert not lines or (lines[0] and lines[-1])
