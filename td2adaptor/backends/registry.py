"""Finding backends: every package under `td2adaptor/backends/` is one, and so is every entry point of the
`td2adaptor.backends` group another distribution installs (`name = "module"`). Adding a backend is adding a
folder; nothing here lists them.

A backend's own diagnostic codes join the catalogue when its module is imported (it calls
`td2adaptor.diagnostics.catalogue.register` and names the stage `DIAGNOSTICS`); `diagnostic_stages` imports
them all, for `td2adaptor explain` and the generated documentation.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys
from functools import cache
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from importlib.metadata import EntryPoint

    from td2adaptor.diagnostics.catalogue import Stage
    from td2adaptor.generation.backend import Backend

ENTRY_POINT_GROUP = "td2adaptor.backends"


def entry_points() -> list[EntryPoint]:
    """The entry points of ENTRY_POINT_GROUP that installed distributions declare.

    `importlib.metadata` costs tens of milliseconds to import and to ask (it parses every distribution's
    metadata), which the pre-commit `check` of an unchanged project would spend to learn that there are none.
    So the `entry_points.txt` files it would read are looked at first: when none of them names the group, it
    cannot find any. It is asked whenever it might: a file names the group, a `sys.path` entry is not a
    folder (a zip), or a finder other than the standard one can find distributions.
    """
    if not _may_declare(ENTRY_POINT_GROUP):
        return []
    from importlib.metadata import entry_points as find

    return list(find(group=ENTRY_POINT_GROUP))


def _may_declare(group: str) -> bool:
    import importlib.machinery

    for finder in sys.meta_path:
        if finder is not importlib.machinery.PathFinder and hasattr(finder, "find_distributions"):
            return True
    needle = group.encode()
    for entry in sys.path:
        root = entry or "."
        try:
            with os.scandir(root) as found:
                infos = [e.name for e in found if e.name.lower().endswith((".dist-info", ".egg-info"))]
        except NotADirectoryError:
            return True  # a zip file or some other kind of entry: importlib.metadata knows
        except OSError:
            continue  # missing: importlib.metadata finds nothing there either
        for name in infos:
            try:
                with open(os.path.join(root, name, "entry_points.txt"), "rb") as fh:
                    if needle in fh.read():
                        return True
            except OSError:
                continue
    return False


def builtin() -> list[str]:
    """The backends td2adaptor ships (its folders), in `all` order: what docs/diagnostics.md documents."""
    import td2adaptor.backends as package

    return [name for name, module in modules().items() if module == f"{package.__name__}.{name}"]


@cache
def modules() -> dict[str, str]:
    """Backend name → module, in the order `--backend all` runs them (each backend's ORDER, then name)."""
    import td2adaptor.backends as package

    found: dict[str, str] = {}
    for info in pkgutil.iter_modules(package.__path__):
        if info.ispkg and not info.name.startswith("_"):
            found[info.name] = f"{package.__name__}.{info.name}"
    for ep in entry_points():
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


def diagnostic_stages(names: list[str] | None = None) -> tuple[Stage, ...]:
    """The stages of the backends' own codes (of `names`, or of every available backend), each imported so
    that its codes are in the catalogue; in `all` order."""
    found = []
    for name in available() if names is None else names:
        stage = getattr(load(name), "DIAGNOSTICS", None)
        if stage is not None:
            found.append(stage)
    return tuple(found)


def load(name: str) -> Backend:
    module: Any = importlib.import_module(modules()[name])
    return module  # type: ignore[no-any-return]
