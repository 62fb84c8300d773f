"""`td2adaptor.generate` and `td2adaptor.check` for build scripts: the CLI's semantics, no click needed.

Both build their targets with `generation.targets.targets`, as the CLI does, so options given together
with the project configuration override it by the same rules.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from td2adaptor.compiler.build import Outcome
from td2adaptor.compiler.build import check as _check
from td2adaptor.compiler.build import generate as _generate
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.targets import Options, Target, targets

PathLike = str | Path


def _targets(
    tds: PathLike | Sequence[PathLike] | None,
    config: PathLike | None,
    *,
    backends: Sequence[str] | None,
    output: PathLike | None,
    interfaces: Sequence[PathLike],
    values: Mapping[str, Any] | None,
    package_name: str | None,
    partial: bool,
    strict: bool,
    options: Mapping[str, Any] | None,
) -> tuple[list[Target], Outcome | None]:
    paths = [] if tds is None else [tds] if isinstance(tds, (str, Path)) else list(tds)
    given = Options(
        backends=tuple(backends or ()),
        output=Path(output) if output is not None else None,
        interfaces=tuple(Path(p) for p in interfaces),
        values=tuple(sorted((values or {}).items())),
        package_name=package_name,
        partial=partial,
        strict=strict,
        options=tuple(sorted((options or {}).items())),
    )
    diags = Diagnostics()
    found = targets([Path(p) for p in paths], given, diags, config=Path(config) if config is not None else None)
    if found is None:
        return [], Outcome(list(diags))
    return found, None


def generate(
    tds: PathLike | Sequence[PathLike] | None = None,
    *,
    backends: Sequence[str] | None = None,
    output: PathLike | None = None,
    interfaces: Sequence[PathLike] = (),
    values: Mapping[str, Any] | None = None,
    package_name: str | None = None,
    partial: bool = False,
    strict: bool = False,
    force: bool = False,
    config: PathLike | None = None,
    use_cache: bool = True,
    options: Mapping[str, Any] | None = None,
) -> Outcome:
    """Generate adaptors for `tds` (or the project configuration when `tds` is None) and write them.

    Defaults with TDs: every backend, into `generated/`. `options` are backend options
    (`{"mros.sequence_capacity": 64}`), as `--option` gives them. `Outcome.ok` is False with diagnostics when anything
    was invalid; then nothing was written.
    """
    found, failed = _targets(
        tds,
        config,
        backends=backends,
        output=output,
        interfaces=interfaces,
        values=values,
        package_name=package_name,
        partial=partial,
        strict=strict,
        options=options,
    )
    return failed or _generate(found, force=force, use_cache=use_cache)


def check(
    tds: PathLike | Sequence[PathLike] | None = None,
    *,
    backends: Sequence[str] | None = None,
    output: PathLike | None = None,
    interfaces: Sequence[PathLike] = (),
    values: Mapping[str, Any] | None = None,
    package_name: str | None = None,
    partial: bool = False,
    strict: bool = False,
    config: PathLike | None = None,
    use_cache: bool = True,
    options: Mapping[str, Any] | None = None,
) -> Outcome:
    """Whether the generated code on disk is current (`Outcome.ok`); `Outcome.stale` lists what is not."""
    found, failed = _targets(
        tds,
        config,
        backends=backends,
        output=output,
        interfaces=interfaces,
        values=values,
        package_name=package_name,
        partial=partial,
        strict=strict,
        options=options,
    )
    return failed or _check(found, use_cache=use_cache)
