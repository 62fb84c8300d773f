"""The build, the compiler's drive through the whole pipeline: TDs → models (`pipeline`) → in-memory trees per
backend → disk (via `generation.emit`), or a comparison with disk (`check`). The CLI's `gen`/`check` and build
scripts use the same functions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from td2adaptor.backends import registry as backend_registry
from td2adaptor.compiler.units import compile_units
from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, escalate
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.generation.emit import EmitReport, discard, plan, stage, swap
from td2adaptor.generation.targets import Target

if TYPE_CHECKING:  # the model loads when something is compiled: a result-cache hit needs none of it
    from td2adaptor.compiler.pipeline import Input
    from td2adaptor.frontend.legacy import LegacyInput
    from td2adaptor.model import Model


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
    optional: frozenset[str] = frozenset(),
    backend_options: Sequence[tuple[str, Any]] = (),
) -> dict[str, GeneratedTree] | None:
    """Every requested backend's tree, or None when a backend reported an error.

    `optional` backends are the ones `all` brought in without being named: one that cannot represent the TD
    is skipped with a warning (GEN807) while another backend generates, so `gen td.json` makes what it can
    and says what it left out. A backend named explicitly, or --strict, keeps its errors.
    """
    if package_name and package_name != model.package_name:  # else lowering has checked and applied it
        from td2adaptor.lowering.rosnames import package_name_problem

        problem = package_name_problem(package_name)
        if problem:
            diags.error("GEN800", f"package name {package_name!r} {problem}")
            return None
        model = replace(model, package_name=package_name)
    known = backend_registry.available() if backend_options else []  # imports every backend: only when needed
    problems = [key for key, _ in backend_options if key.split(".", 1)[0] not in known or "." not in key]
    for key in problems:  # options of a known backend that is not generated this time are left alone
        diags.error(
            "GEN808",
            f"option {key!r} names no backend (known: {', '.join(known)})",
            hint="backend options are <backend>.<name>, e.g. mros.sequence_capacity",
        )
    if problems:
        return None
    # the model carries the package name: backends are not told it a second time
    options = GenOptions(partial=partial, extra=tuple(backend_options))
    results: list[tuple[str, GeneratedTree, list[Diagnostic]]] = []
    for name in names:
        local = Diagnostics()
        tree = backend_registry.load(name).generate(model, options, local)
        results.append((name, tree, escalate(local) if strict else list(local)))
    failed = {name for name, _, found in results if any(d.severity is Severity.ERROR for d in found)}
    skip = not strict and failed <= optional and len(failed) < len(names)
    trees: dict[str, GeneratedTree] = {}
    for name, tree, found in results:
        if name in failed and skip:
            first = next(d for d in found if d.severity is Severity.ERROR)
            count = sum(d.severity is Severity.ERROR for d in found)
            diags.warning(
                "GEN807",
                f"{name} backend skipped: it cannot represent this TD ({first.code}: {first.message}"
                + (f"; {count - 1} more" if count > 1 else "")
                + ")",
                first.pointer,
                hint=f"--partial generates what it can; -b {name} shows every problem",
            )
            continue
        diags.extend(found)
        trees[name] = tree
    return None if failed and not skip else trees


@dataclass
class Outcome:
    """What `generate` or `check` did: diagnostics, and per output directory what changed (or would)."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    reports: dict[Path, EmitReport] = field(default_factory=dict)
    ok: bool = False

    @property
    def stale(self) -> list[str]:
        """`A path` (new), `M path` (changed), `D path` (removed), across all output directories."""
        out = []
        for root, rep in sorted(self.reports.items()):
            out += [f"A {root / p}" for p in rep.written if not (root / p).exists()]
            out += [f"M {root / p}" for p in rep.written if (root / p).exists()]
            out += [f"D {root / p}" for p in rep.removed]
        return out


def build(
    targets: Sequence[Target], diags: Diagnostics, *, use_cache: bool = True, parallel: bool = False
) -> dict[Path, GeneratedTree] | None:
    """Compile every TD of every target and generate; trees merged per output directory `OUT/<backend>`, then
    finished by the backends that have a `finish` (see `generation.backend`).

    With `use_cache`, the trees and diagnostics of an identical earlier build come from the result cache (its
    key covers td2adaptor's code and templates, the targets, every input file and interface folder), so the
    pre-commit `check` of an unchanged project imports no backend and renders nothing.
    """
    key = _build_key(targets) if use_cache else None
    if key is None:
        return _build(targets, diags, use_cache=use_cache, parallel=parallel)
    from td2adaptor.compiler import resultcache

    def fresh() -> tuple[list[Diagnostic], dict[Path, GeneratedTree] | None]:
        local = Diagnostics()
        trees = _build(targets, local, use_cache=True, parallel=parallel)
        return list(local), trees

    found, trees = resultcache.cached(key, fresh)
    diags.extend(found)
    return trees  # type: ignore[no-any-return]


def _build_key(targets: Sequence[Target]) -> str | None:
    """The result-cache key of a build, or None when it cannot be cached: no cache directory, an input on
    stdin, or a backend installed by another distribution (its code is not in td2adaptor's fingerprint)."""
    from td2adaptor.support import cache

    if cache.cache_dir() is None:
        return None
    if backend_registry.entry_points():
        return None
    from td2adaptor.compiler import resultcache

    sources = [str(td) for target in targets for td in target.tds]
    folders = [Path(folder) for target in targets for folder in target.interfaces]
    return resultcache.key(sources, folders, ("build", str(Path.cwd()), tuple(targets)))


def _build(
    targets: Sequence[Target], diags: Diagnostics, *, use_cache: bool, parallel: bool
) -> dict[Path, GeneratedTree] | None:
    from td2adaptor.compiler.pipeline import compile

    merged: dict[Path, GeneratedTree] = {}
    backends: dict[Path, str] = {}
    origin: dict[Path, str] = {}  # each generated file: the input that generated it first
    ok = True
    for target in targets:
        names, problem = resolve_backends(target.backends)
        if problem:
            diags.error("GEN804", problem)
            ok = False
            continue
        for unit in compile_units(target.tds):
            result = compile(
                [str(td) for td in unit],
                interfaces=list(target.interfaces),
                values=dict(target.values),
                strict=target.strict,
                package=target.package_name,
                use_cache=use_cache,
                parallel=parallel,
            )
            diags.extend(result.diagnostics)
            if result.model is None:
                ok = False
                continue
            local = Diagnostics()
            trees = generate_trees(
                result.model,
                names,
                local,
                partial=target.partial,
                package_name=target.package_name,
                strict=target.strict,
                optional=frozenset(n for n in names if n not in target.backends)
                if "all" in target.backends
                else frozenset(),
                backend_options=target.options,
            )
            diags.extend(_locate(local, unit, result.input))
            if trees is None:
                ok = False
                continue
            for name, tree in trees.items():
                root = target.output / name
                backends[root] = name
                into = merged.setdefault(root, GeneratedTree())
                for rel, data in tree:
                    if rel in into.files and into.files[rel] != data:
                        diags.add(
                            "GEN805",
                            Severity.ERROR,
                            f"two inputs generate different {root / rel} (the other: {origin[root / rel]})",
                            hint="give them different package names (a target's --package-name names every input)",
                            file=str(unit[0]),
                        )
                        ok = False
                    into.files[rel] = data
                    origin.setdefault(root / rel, ", ".join(map(str, unit)))
                into.executable |= tree.executable
    if not ok:
        return None
    for root, name in backends.items():
        finish = getattr(backend_registry.load(name), "finish", None)
        if finish is not None:
            merged[root] = finish(merged[root])
    return merged


def _locate(diags: Diagnostics, unit: Sequence[Path], inp: Input | None = None) -> list[Diagnostic]:
    """Backends point into the TD; give their diagnostics the TD's file:line:col (for RosClasses files: the
    line of the config file the affordance came from). `inp` is what the compile read; without it (the
    model came from the result cache), each file of the unit is read here, once."""
    if all(d.file for d in diags):
        return list(diags)
    if inp is None:
        from td2adaptor.frontend.jsonsrc import load_path
        from td2adaptor.frontend.legacy import is_legacy, to_reference_td

        docs = [load_path(str(td), Diagnostics()) for td in unit]
        if docs[0] is not None and is_legacy(docs[0].data):  # a unit of several files is all RosClasses files
            read = [doc for doc in docs if doc is not None]
            if len(read) < len(docs) or not all(is_legacy(doc.data) for doc in read):
                return list(diags)
            return _remap(diags, to_reference_td(read, Diagnostics()))
        doc = docs[0]
        return [d if d.file or doc is None else doc.locate(d) for d in diags]
    if inp.legacy is not None:
        return _remap(diags, inp.legacy)
    return [d if d.file else inp.doc.locate(d) for d in diags]


def _remap(diags: Diagnostics, legacy: LegacyInput) -> list[Diagnostic]:
    out = []
    for d in diags:
        if not d.file:
            d, doc = legacy.remap(d)
            d = d if doc is None else doc.locate(d)
        out.append(d)
    return out


def generate(
    targets: Sequence[Target], *, force: bool = False, use_cache: bool = True, parallel: bool = False
) -> Outcome:
    """Generate and write; nothing is written when any input is invalid or any write would be refused."""
    diags = Diagnostics()
    outcome = Outcome()
    trees = build(targets, diags, use_cache=use_cache, parallel=parallel)
    if trees is not None:
        plans = {root: plan(tree, root, diags, force=force) for root, tree in trees.items()}
        if all(p is not None for p in plans.values()):
            reports = {root: rep for root, rep in plans.items() if rep is not None}
            if _write_all(trees, reports, diags):
                outcome.reports.update(reports)
                outcome.ok = not diags.has_errors
    outcome.diagnostics = list(diags)
    return outcome


def _write_all(trees: Mapping[Path, GeneratedTree], reports: Mapping[Path, EmitReport], diags: Diagnostics) -> bool:
    """Stage every output directory first and swap them in only when all staged: a failure (a full disk, a
    name the file system refuses) leaves every directory as it was."""
    staged: dict[Path, Path] = {}
    try:
        for root, rep in reports.items():
            new = stage(trees[root], root, rep)
            if new is not None:
                staged[root] = new
    except OSError as exc:
        for new in staged.values():
            discard(new)
        diags.error(
            "GEN806",
            f"could not write {root}: {exc.strerror or exc}",
            hint="nothing was changed; free space or fix the permissions and run again",
        )
        return False
    for root, new in staged.items():
        swap(new, root)
    return True


def check(targets: Sequence[Target], *, use_cache: bool = True, parallel: bool = False) -> Outcome:
    """Regenerate in memory and compare with disk; never writes. `ok` is True when everything is current."""
    diags = Diagnostics()
    outcome = Outcome()
    trees = build(targets, diags, use_cache=use_cache, parallel=parallel)
    current = trees is not None
    if trees is not None:
        for root, tree in trees.items():
            rep = plan(tree, root, Diagnostics(), force=True)
            assert rep is not None
            outcome.reports[root] = rep
            from td2adaptor.generation.emit import MANIFEST, _manifest_bytes, _read

            if rep.written or rep.removed or _read(root / MANIFEST) != _manifest_bytes(tree):
                current = False
    outcome.ok = current and not diags.has_errors
    outcome.diagnostics = list(diags)
    return outcome


def target(
    tds: str | Path | Sequence[str | Path],
    *,
    backends: Sequence[str] = ("all",),
    output: str | Path = "generated",
    interfaces: Sequence[str | Path] = (),
    values: Mapping[str, Any] | None = None,
    package_name: str | None = None,
    partial: bool = False,
    strict: bool = False,
) -> Target:
    """A Target for `tds` from plain arguments, built by `targets.targets` as the CLI and `td2adaptor.generate`
    build theirs (a shorthand for scripts and tests that call `generate`/`check` here directly)."""
    from td2adaptor.generation.targets import Options, targets

    paths = [tds] if isinstance(tds, (str, Path)) else list(tds)
    options = Options(
        backends=tuple(backends),
        output=Path(output),
        interfaces=tuple(Path(p) for p in interfaces),
        values=tuple(sorted((values or {}).items())),
        package_name=package_name,
        partial=partial,
        strict=strict,
    )
    found = targets([Path(p) for p in paths], options, Diagnostics())
    assert found is not None and len(found) == 1  # with TDs given, targets() makes exactly one and cannot fail
    return found[0]
