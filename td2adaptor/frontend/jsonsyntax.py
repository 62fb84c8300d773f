"""Explaining a JSON syntax error where the writer made it, not where the parser gave up.

`json` reports a trailing comma at the next line's closing bracket, a missing comma at the next member and an
unclosed document at its very end. Hand-written TDs mostly fail in those three ways; this module finds the
place to show (the comma, the end of the value before the missing comma, the bracket left open) and a hint.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

_WHITESPACE = " \t\r\n"


@dataclass(frozen=True)
class SyntaxProblem:
    message: str
    offset: int  # character offset of the place to show
    hint: str


def explain(text: str, exc: json.JSONDecodeError) -> SyntaxProblem:
    """The problem behind `exc`, at the place a person would fix it."""
    pos = exc.pos
    before = _previous_significant(text, pos)
    following = text[pos : pos + 1]
    if text[pos:].strip(_WHITESPACE) == "":
        opened = _unclosed(text)
        if opened is not None:
            bracket = text[opened]
            closer = "}" if bracket == "{" else "]"
            return SyntaxProblem(
                f"invalid JSON: the '{bracket}' opened here is never closed (the text ends first)",
                opened,
                f"add the missing '{closer}' (and check the brackets inside it)",
            )
    if before is not None and text[before] == "," and following in ("}", "]"):
        return SyntaxProblem(
            f"invalid JSON: a trailing comma before '{following}'",
            before,
            "remove this comma: JSON allows none after the last member or element",
        )
    if exc.msg == "Expecting ',' delimiter" and before is not None:
        return SyntaxProblem(
            "invalid JSON: a ',' is missing after this value",
            before + 1,
            "separate members and elements with ','",
        )
    if exc.msg.startswith("Expecting property name") and following == "'":
        return SyntaxProblem(
            f"invalid JSON: {exc.msg}", pos, "JSON strings and keys use double quotes, not single quotes"
        )
    if text[pos : pos + 2] in ("//", "/*"):
        return SyntaxProblem("invalid JSON: comments are not allowed", pos, "remove the comment")
    return SyntaxProblem(
        f"invalid JSON: {exc.msg}",
        pos,
        "JSON needs double-quoted keys and strings, ',' between members, no trailing commas and no comments",
    )


def _previous_significant(text: str, pos: int) -> int | None:
    i = pos - 1
    while i >= 0 and text[i] in _WHITESPACE:
        i -= 1
    return i if i >= 0 else None


def _unclosed(text: str) -> int | None:
    """Offset of the innermost bracket still open at the end of `text` (strings and escapes skipped)."""
    stack: list[int] = []
    in_string = escaped = False
    for i, ch in enumerate(text):
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "{[":
            stack.append(i)
        elif ch in "}]" and stack:
            stack.pop()
    return stack[-1] if stack else None
