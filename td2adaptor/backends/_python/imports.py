"""Import blocks of generated Python, written the way ruff's isort and formatter would leave them.

Sections: standard library, third party, local (relative); in each, `import x` lines before `from x import`
lines, modules by name, imported names by isort's order-by-type (CONSTANTS, Classes, functions). A `from`
line longer than the line length is exploded one name per line, with a trailing comma.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from td2adaptor.backends._python.text import LINE

#: the standard-library modules generated code imports (everything else but relative imports is third party)
STDLIB = frozenset({"array", "collections", "typing"})


def member_key(member: str) -> tuple[int, str, str]:
    """isort's order-by-type for one imported name (`Name` or `Name as alias`), numbers in natural order as
    ruff compares them (`check_uint8` before `check_uint32`)."""
    name = member.split(" as ")[0]
    kind = 0 if name.isupper() and len(name) > 1 else 1 if name[:1].isupper() else 2
    return kind, re.sub(r"\d+", lambda digits: digits[0].zfill(20), name.lower()), member


def import_line(module: str, members: Iterable[str]) -> str:
    """`from module import ...`, exploded over several lines when too long."""
    names = sorted(set(members), key=member_key)
    line = f"from {module} import {', '.join(names)}"
    if len(line) <= LINE:
        return line
    return f"from {module} import (\n" + "".join(f"    {n},\n" for n in names) + ")"


def _section(module: str) -> int:
    if module.startswith("."):
        return 2
    return 0 if module.split(".")[0] in STDLIB else 1


def import_block(members: Iterable[tuple[str, str]], modules: Iterable[str] = ()) -> list[str]:
    """The lines of an import block: `members` are (module, name) for `from` imports, `modules` plain imports.

    Sections are separated by an empty string (one blank line when printed).
    """
    grouped: dict[str, set[str]] = {}
    for module, name in members:
        grouped.setdefault(module, set()).add(name)
    sections: list[list[str]] = [[], [], []]
    for module in sorted(set(modules)):
        sections[_section(module)].append(f"import {module}")
    for module in sorted(grouped, key=str.lower):
        sections[_section(module)].append(import_line(module, grouped[module]))
    lines: list[str] = []
    for section in sections:
        if section:
            lines += ([""] if lines else []) + section
    return lines
