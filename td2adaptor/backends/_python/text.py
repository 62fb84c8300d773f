"""Docstrings and calls of generated Python: TD text wrapped and escaped, calls split, so that no line outgrows
the package's ruff.toml (and ruff's formatter leaves them as they are)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from td2adaptor.generation import textsafe as ts

#: the line length of the generated packages (their ruff.toml)
LINE = 120


def wrap(text: str, width: int, *, collapse: bool = False) -> str:
    """`text` wrapped to `width` escaped columns; `collapse` joins its lines into one paragraph first."""
    return "\n".join(ts.wrap_lines(" ".join(text.split()) if collapse else text, width))


def docstring(
    paragraphs: Iterable[str | None], indent: str, *, margin: int = 4, collapse: bool = False, fallback: str = ""
) -> str:
    """A docstring literal of the non-empty paragraphs, each wrapped so that, indented and escaped, it fits.

    `margin` is what a line may need besides its text (the quotes of a one-line docstring).
    """
    width = LINE - len(indent) - margin
    blocks = [wrap(p, width, collapse=collapse) for p in paragraphs if p and p.strip()]
    return ts.py_docstring("\n\n".join(b for b in blocks if b), indent, fallback=fallback)


def call_lines(lead: str, func: str, args: Sequence[str], tail: str, indent: int) -> list[str]:
    """`lead` `func(args)` `tail` at `indent` columns as ruff's formatter lays it out: on one line if it fits,
    else the arguments on a line of their own, else one per line with a trailing comma."""
    inner = ", ".join(args)
    one = f"{lead}{func}({inner}){tail}"
    if indent + len(one) <= LINE:
        return [one]
    if indent + 4 + len(inner) <= LINE:
        return [f"{lead}{func}(", f"    {inner}", f"){tail}"]
    return [f"{lead}{func}(", *(f"    {arg}," for arg in args), f"){tail}"]
