"""Finding backends: every package under `td2adaptor/backends/` is one, and so is every entry point of the
`td2adaptor.backends` group another distribution installs (`name = "module"`). Adding a backend is adding a
folder; nothing here lists them.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache
from importlib.metadata import entry_points
from typing import Any

from td2adaptor.generation.backend import Backend

ENTRY_POINT_GROUP = "td2adaptor.backends"


@cache
def modules() -> dict[str, str]:
    """Backend name → module, in the order `--backend all` runs them (each backend's ORDER, then name)."""
    import td2adaptor.backends as package

    found: dict[str, str] = {}
    for info in pkgutil.iter_modules(package.__path__):
        if info.ispkg and not info.name.startswith("_"):
            found[info.name] = f"{package.__name__}.{info.name}"
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep.value)
    return dict(sorted(found.items(), key=lambda kv: (_order(kv[1]), kv[0])))


def _order(module: str) -> int:
    try:
        return int(getattr(importlib.import_module(module), "ORDER", 1000))
    except ImportError:
        return 1000


def available() -> list[str]:
    """Backends whose module imports in this installation, in `all` order."""
    out = []
    for name, module in modules().items():
        try:
            importlib.import_module(module)
        except ImportError:
            continue
        out.append(name)
    return out


def load(name: str) -> Backend:
    module: Any = importlib.import_module(modules()[name])
    return module  # type: ignore[no-any-return]
