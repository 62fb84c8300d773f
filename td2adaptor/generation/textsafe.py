"""Turning untrusted TD text into safe literals of the languages we generate.

Every string that comes from a TD (names are validated separately; titles, descriptions, enum values,
defaults) reaches generated code only through these functions, so no TD text can end a literal or a
comment and become code.
"""

from __future__ import annotations

import json
import re

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f\u2028\u2029\u0085]")


def py_docstring(text: str | None, indent: str = "    ", *, fallback: str = "") -> str:
    """A triple-quoted Python docstring whose content cannot close it: `\\` and every `"` are escaped."""
    body = (text if text else fallback).strip()
    body = body.replace("\\", "\\\\").replace('"', '\\"')
    body = _CONTROL.sub(
        lambda m: f"\\x{ord(m.group()):02x}" if ord(m.group()) < 256 else f"\\u{ord(m.group()):04x}", body
    )
    lines = [line.rstrip() for line in body.replace("\r\n", "\n").replace("\r", "\n").split("\n")]
    if len(lines) == 1:
        return f'"""{lines[0]}"""'
    return (
        '"""'
        + lines[0]
        + "\n"
        + "\n".join((indent + line) if line else "" for line in lines[1:])
        + "\n"
        + indent
        + '"""'
    )


def py_str(text: str) -> str:
    """A Python string literal (double-quoted, ASCII-only escapes for anything unusual)."""
    return json.dumps(text, ensure_ascii=True)


def py_comment(text: str) -> str:
    """A single-line `#` comment body: newlines and control characters cannot start a new line of code."""
    return _CONTROL.sub(" ", text.replace("\r", " ").replace("\n", " ")).strip()


def c_str(text: str) -> str:
    """A C/C++ string literal: only printable ASCII kept verbatim, everything else as octal escapes."""
    out = []
    for byte in text.encode("utf-8"):
        ch = chr(byte)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 0x20 <= byte < 0x7F and ch != "?":  # '?' escaped: no trigraphs in C++98
            out.append(ch)
        else:
            out.append(f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def c_comment(text: str) -> str:
    """Text for inside a `/* ... */` or `//` comment: cannot close the comment nor continue a line.

    Backslashes go first (so `*\\` cannot turn into `*/`), then comment delimiters, then `??` (trigraphs,
    of which `??/` is a backslash in C++98).
    """
    text = text.replace("\\", "/")
    while "*/" in text or "/*" in text or "??" in text:
        text = text.replace("*/", "* /").replace("/*", "/ *").replace("??", "? ?")
    return _CONTROL.sub(" ", text.replace("\r", " ").replace("\n", " ")).strip()


def xml_text(text: str) -> str:
    """Text content for XML (package.xml): escaped, control characters dropped."""
    text = _CONTROL.sub(" ", text)
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def md_inline(text: str) -> str:
    """Inline Markdown text (a heading, a table cell): one line, no table, link, code or HTML syntax of its own.

    Control characters and line breaks become spaces (so the text cannot start a row or a block), and every
    character Markdown gives a meaning inline is backslash-escaped.
    """
    text = " ".join(_CONTROL.sub(" ", text).split())
    for ch in "\\`*_[]<>|#":
        text = text.replace(ch, "\\" + ch)
    return text


# ---------------------------------------------------------------------------------------------------------
# wrapping docstring text (measured as it will be written, escapes included)

_BREAKS = re.compile(r"\r\n|\r|\n|\u2028|\u2029|\u0085")
_JUNK = re.compile(r"[\x00-\x1f\x7f]")


def _cost(text: str) -> int:
    """Columns `text` takes once escaped by `py_docstring` (non-ASCII counted wide, to be safe)."""
    wide = 0 if text.isascii() else sum(1 for ch in text if not ch.isascii())
    return len(text) + text.count('"') + text.count("\\") + wide


def _wrap_line(line: str, width: int) -> list[str]:
    line = _JUNK.sub(" ", line)
    words = [w for w in line.split(" ") if w]
    # most text is plain ASCII without quotes or backslashes: there a word's cost is its length
    cost_of = len if line.isascii() and '"' not in line and "\\" not in line else _cost
    out: list[str] = []
    current = ""
    used = 0  # cost_of(current), kept incrementally: wrapping stays linear in the text's length
    for word in words:
        cost = cost_of(word)
        while cost > width:  # a very long word: split it between characters (before escaping: safe)
            cut = taken = 0
            while taken + cost_of(word[cut]) <= width:
                taken += cost_of(word[cut])
                cut += 1
            if current:
                out.append(current)
                current, used = "", 0
            out.append(word[:cut])
            word = word[cut:]
            cost -= taken
        if current and used + 1 + cost > width:
            out.append(current)
            current, used = word, cost
        else:
            current, used = (f"{current} {word}", used + 1 + cost) if current else (word, cost)
    if current:
        out.append(current)
    return out


def wrap_lines(text: str, width: int) -> list[str]:
    """Greedy word wrap for docstrings: no line, once escaped, is wider than `width`; line breaks in `text`
    are kept (blank lines collapse to one), control characters become spaces."""
    lines: list[str] = []
    for raw in _BREAKS.split(text.strip()):
        wrapped = _wrap_line(raw, width)
        if wrapped:
            lines.extend(wrapped)
        elif lines and lines[-1]:
            lines.append("")
    while lines and not lines[-1]:
        lines.pop()
    return lines
