"""Names a generated module must not give to message classes or parameters, derived in one place.

They are what the module refers to besides messages: the names its runtime modules define (read from their
source, so a new helper is reserved as soon as it exists), names its template uses, Python's keywords and
builtins.
"""

from __future__ import annotations

import ast
import builtins
import keyword
from collections.abc import Collection, Iterable


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


#: names a generated method already has besides message fields: its own parameters (`timeout` of call_X and
#: get_X_value, `mission_id`, `request`, `goal`, `self`) and locals of the method bodies (`item`, `response`)
METHOD_NAMES = frozenset({"self", "timeout", "mission_id", "request", "response", "goal", "item"})


def param_name(name: str, reserved: Collection[str]) -> str:
    """A message field as a keyword parameter of a generated method: the field's name, with a trailing `_`
    when it is a keyword, a builtin, a name of `reserved` (the module's runtime and imported names) or of
    METHOD_NAMES. The rclpy and rospy generators both use it, so one TD gives both packages the same names."""
    clash = keyword.iskeyword(name) or name in _BUILTINS or name in METHOD_NAMES or name in reserved
    return name + "_" if clash else name


_BUILTINS = frozenset(dir(builtins))
