"""Catalogue entries for `td2adaptor explain CODE`, as text or JSON; the CLI only prints them."""

from __future__ import annotations

from collections.abc import Iterable

from td2adaptor.diagnostics.catalogue import CATALOGUE, Entry, lookup


def unknown_codes(codes: Iterable[str]) -> list[str]:
    """The given codes the catalogue does not list (case-insensitive, as users type them)."""
    return [c for c in codes if c.upper() not in CATALOGUE]


def _text(entry: Entry) -> str:
    stage = entry.stage
    lines = [
        f"{entry.code} ({entry.severity_text()}): {entry.meaning}",
        f"  stage: {stage.prefix}xx {stage.title} ({stage.modules})",
    ]
    if entry.hint:
        lines.append(f"  hint: {entry.hint}")
    return "\n".join(lines)


def explain_text(codes: Iterable[str]) -> str:
    """One block per code, separated by blank lines."""
    return "\n\n".join(_text(lookup(c)) for c in codes)


def explain_json(codes: Iterable[str]) -> list[dict[str, object]]:
    """One object per code: the entry's fields, severities as strings."""
    out: list[dict[str, object]] = []
    for code in codes:
        entry = lookup(code)
        out.append(
            {
                "code": entry.code,
                "severity": entry.severity.value,
                "severities": [s.value for s in entry.severities],
                "when": entry.when,
                "meaning": entry.meaning,
                "hint": entry.hint,
                "stage": entry.stage.title,
            }
        )
    return out
