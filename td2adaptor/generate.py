"""Generation as a library: model → in-memory trees per backend → disk (via `emit`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from td2adaptor import backends as backend_registry
from td2adaptor.backends import GeneratedTree, GenOptions
from td2adaptor.diagnostics import Diagnostics, Severity, escalate
from td2adaptor.emit import EmitReport, plan, write
from td2adaptor.model import Model
from td2adaptor.rosnames import package_name_problem


def resolve_backends(requested: Sequence[str]) -> tuple[list[str], str | None]:
    """Expand `all`, drop duplicates, keep the documented order; an error message for unknown names."""
    available = backend_registry.available()
    names: list[str] = []
    for name in requested:
        if name == "all":
            names.extend(available)
        elif name in available:
            names.append(name)
        else:
            known = ", ".join([*available, "all"])
            return [], f"unknown backend {name!r} (known: {known})"
    order = {n: i for i, n in enumerate(available)}
    return sorted(dict.fromkeys(names), key=order.__getitem__), None


def generate_trees(
    model: Model,
    names: Sequence[str],
    diags: Diagnostics,
    *,
    partial: bool = False,
    package_name: str | None = None,
    strict: bool = False,
) -> dict[str, GeneratedTree] | None:
    """Every requested backend's tree, or None when any backend reported an error."""
    if package_name:
        problem = package_name_problem(package_name)
        if problem:
            diags.error("GEN800", f"package name {package_name!r} {problem}")
            return None
        model = replace(model, package_name=package_name)
    options = GenOptions(package_name=package_name, partial=partial)
    trees: dict[str, GeneratedTree] = {}
    local = Diagnostics()
    for name in names:
        trees[name] = backend_registry.load(name).generate(model, options, local)
    found = escalate(local) if strict else list(local)
    diags.extend(found)
    if any(d.severity is Severity.ERROR for d in found):
        return None
    return trees


def write_trees(
    trees: dict[str, GeneratedTree], output: Path, diags: Diagnostics, *, force: bool = False
) -> dict[str, EmitReport] | None:
    """Write every tree under `output/<backend>/`; nothing at all is written if any tree is refused."""
    plans: dict[str, EmitReport] = {}
    for name, tree in trees.items():
        rep = plan(tree, output / name, diags, force=force)
        if rep is None:
            return None
        plans[name] = rep
    for name, rep in plans.items():
        write(trees[name], output / name, rep)
    return plans
