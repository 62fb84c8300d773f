"""Diagnostics as values: every stage appends to a collector, the CLI reports them together.

Each diagnostic carries a stable code, a severity, a message, an optional hint and a JSON pointer into the
document it is about; file/line/column are attached later from the document's source map, so stages never
need to know about text positions.

Every code is listed in `catalogue` (severity, meaning, hint); `Diagnostics.add` refuses a code that is not,
so a new code cannot go undocumented; a backend adds its own codes (`catalogue.register`).
`python -m td2adaptor.cli.docs` writes docs/diagnostics.md.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Any

from td2adaptor.diagnostics.severity import Severity

__all__ = ["Diagnostic", "Diagnostics", "Severity", "escalate", "pointer_join", "pointer_tokens"]


@dataclass(frozen=True)
class Diagnostic:
    code: str
    severity: Severity
    message: str
    pointer: str = ""
    hint: str | None = None
    file: str | None = None
    line: int | None = None
    col: int | None = None

    @property
    def location(self) -> str:
        """`file:line:col` (as much of it as is known)."""
        parts = [self.file or "<input>"]
        if self.line is not None:
            parts.append(str(self.line))
            if self.col is not None:
                parts.append(str(self.col))
        return ":".join(parts)

    def to_json(self) -> dict[str, object]:
        return {
            "code": self.code,
            "severity": self.severity.value,
            "message": self.message,
            "hint": self.hint,
            "pointer": self.pointer,
            "file": self.file,
            "line": self.line,
            "col": self.col,
        }


class Diagnostics:
    """An ordered collector of diagnostics (append-only)."""

    def __init__(self, items: Iterable[Diagnostic] = ()) -> None:
        self._items: list[Diagnostic] = list(items)

    def add(
        self,
        code: str,
        severity: Severity,
        message: str,
        pointer: str = "",
        hint: str | None = None,
        *,
        file: str | None = None,
    ) -> Diagnostic:
        """Record one diagnostic; ValueError for a code missing from the catalogue (a bug, never bad input)."""
        _check_code(code)
        diag = Diagnostic(code, severity, message, pointer, hint, file)
        self._items.append(diag)
        return diag

    def error(self, code: str, message: str, pointer: str = "", hint: str | None = None) -> Diagnostic:
        return self.add(code, Severity.ERROR, message, pointer, hint)

    def warning(self, code: str, message: str, pointer: str = "", hint: str | None = None) -> Diagnostic:
        return self.add(code, Severity.WARNING, message, pointer, hint)

    def info(self, code: str, message: str, pointer: str = "", hint: str | None = None) -> Diagnostic:
        return self.add(code, Severity.INFO, message, pointer, hint)

    def extend(self, other: Iterable[Diagnostic]) -> None:
        self._items.extend(other)

    def append(self, diag: Diagnostic) -> None:
        _check_code(diag.code)
        self._items.append(diag)

    def __iter__(self) -> Iterator[Diagnostic]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    @property
    def items(self) -> tuple[Diagnostic, ...]:
        return tuple(self._items)

    @property
    def has_errors(self) -> bool:
        return any(d.severity is Severity.ERROR for d in self._items)

    def errors(self) -> list[Diagnostic]:
        return [d for d in self._items if d.severity is Severity.ERROR]

    def warnings(self) -> list[Diagnostic]:
        return [d for d in self._items if d.severity is Severity.WARNING]

    def codes(self) -> list[str]:
        return [d.code for d in self._items]


_CATALOGUE: Mapping[str, Any] | None = None


def _check_code(code: str) -> None:
    global _CATALOGUE  # loaded on the first `add`: a result-cache hit adds none (start-up time)
    if _CATALOGUE is None:
        from td2adaptor.diagnostics.catalogue import CATALOGUE

        _CATALOGUE = CATALOGUE
    if code not in _CATALOGUE:
        raise ValueError(f"diagnostic code {code!r} is not in td2adaptor.diagnostics.catalogue: add it there")


def escalate(diags: Iterable[Diagnostic]) -> list[Diagnostic]:
    """`--strict`: every warning becomes an error."""
    return [replace(d, severity=Severity.ERROR) if d.severity is Severity.WARNING else d for d in diags]


def pointer_join(base: str, *tokens: object) -> str:
    """Append JSON-pointer reference tokens (RFC 6901 escaping) to `base`."""
    out = base
    for tok in tokens:
        out += "/" + str(tok).replace("~", "~0").replace("/", "~1")
    return out


def pointer_tokens(pointer: str) -> list[str]:
    """Split a JSON pointer into unescaped reference tokens."""
    if not pointer:
        return []
    return [t.replace("~1", "/").replace("~0", "~") for t in pointer.split("/")[1:]]
