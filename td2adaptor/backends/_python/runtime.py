"""The run-time modules both Python backends copy into their packages unchanged (`verbatim/`): `errors.py`
(what an adaptor raises), `common.py` (defaults, name and timeout checks, `Started`) and `goals.py` (the record
of an action goal that both adaptors' goal handles build on).

The generators read facts from these files instead of repeating them: the error classes a package exports,
the names a generated module must leave alone, the default timeouts its README states.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

from td2adaptor.backends._python.names import defined_names
from td2adaptor.generation.templating import verbatim

VERBATIM = Path(__file__).parent / "verbatim"
SHARED = ("common.py", "errors.py", "goals.py")  # copied into every Python adaptor package, next to its runtime module


def shared_source(name: str) -> bytes:
    """One of the SHARED modules, as it is copied."""
    return verbatim(VERBATIM, name)


@cache
def error_classes() -> tuple[str, ...]:
    """The exception classes of errors.py, in their order there."""
    tree = ast.parse(shared_source("errors.py"))
    return tuple(node.name for node in tree.body if isinstance(node, ast.ClassDef))


@cache
def common_names() -> frozenset[str]:
    """The public names common.py defines (what generated modules import from `.common`)."""
    return frozenset(n for n in defined_names(shared_source("common.py")) if not n.startswith("_"))


@cache
def goals_names() -> frozenset[str]:
    """The public names goals.py defines (what generated modules import from `.goals`)."""
    return frozenset(n for n in defined_names(shared_source("goals.py")) if not n.startswith("_"))


@cache
def constant(name: str) -> str:
    """The literal a module-level constant of common.py is set to (e.g. DEFAULT_TIMEOUT → "10.0")."""
    for node in ast.parse(shared_source("common.py")).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return ast.unparse(node.value)
    raise KeyError(name)
