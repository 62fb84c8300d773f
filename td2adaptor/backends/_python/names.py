"""Names a generated module must not give to message classes or parameters, derived in one place.

They are what the module refers to besides messages: the names its runtime modules define (read from their
source, so a new helper is reserved as soon as it exists), names its template uses, Python's keywords and
builtins.
"""

from __future__ import annotations

import ast
import builtins
import keyword
from collections.abc import Iterable


def defined_names(source: bytes) -> set[str]:
    """The top-level names a Python module defines or imports."""
    names: set[str] = set()
    for node in ast.parse(source).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names |= {t.id for t in targets if isinstance(t, ast.Name)}
    return names


def reserved_names(sources: Iterable[bytes], extra: Iterable[str]) -> frozenset[str]:
    """Every name defined by `sources` (runtime modules), `extra` names, keywords and builtins."""
    names = set(extra) | set(keyword.kwlist) | set(dir(builtins))
    for source in sources:
        names |= defined_names(source)
    return frozenset(names)
