"""The pre-commit no-op without click: `td2adaptor check` (no argument) when the generated code is current.

It says exactly what the click command says in that case, and nothing in any other case: the caller then
runs the click command, which compiles again (from the result cache) and reports stale files, diagnostics
and configuration problems the documented way. So the only thing this module decides is "current".
"""

from __future__ import annotations

import sys

#: what `td2adaptor check` says when nothing is stale (the click command says the same)
CURRENT_LINE = "td2adaptor check: generated code is current"


def check_is_current() -> bool:
    """True, with the verdict printed, when the project configuration's generated code is current and no
    error was found; False (nothing printed) otherwise, including on any failure of its own."""
    try:
        from td2adaptor.api import check

        outcome = check()
        if not outcome.ok or any(d.severity.value == "error" for d in outcome.diagnostics):
            return False
    except Exception:  # noqa: BLE001 - the click command reports whatever this ran into, the documented way
        return False
    print(CURRENT_LINE, file=sys.stderr)
    return True
