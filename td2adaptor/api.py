"""`td2adaptor.generation.build` and `td2adaptor.check` for build scripts: the CLI's semantics, no click needed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.build import Outcome
from td2adaptor.generation.build import check as _check
from td2adaptor.generation.build import generate as _generate
from td2adaptor.generation.build import target as _target
from td2adaptor.generation.targets import Target, find, load

PathLike = str | Path


def _targets(
    tds: PathLike | Sequence[PathLike] | None, config: PathLike | None, options: dict[str, Any]
) -> tuple[list[Target], Outcome | None]:
    if tds is not None:
        return [_target(tds, **options)], None
    diags = Diagnostics()
    path = Path(config) if config is not None else find()
    if path is None:
        diags.error("CFG907", "no TD given and no td2adaptor.toml or [tool.td2adaptor] in pyproject.toml found")
        return [], Outcome(list(diags))
    loaded = load(path, diags)
    if loaded is None:
        return [], Outcome(list(diags))
    return list(loaded.targets), None


def generate(
    tds: PathLike | Sequence[PathLike] | None = None,
    *,
    backends: Sequence[str] = ("all",),
    output: PathLike = "generated",
    interfaces: Sequence[PathLike] = (),
    values: Mapping[str, Any] | None = None,
    package_name: str | None = None,
    partial: bool = False,
    strict: bool = False,
    force: bool = False,
    config: PathLike | None = None,
    use_cache: bool = True,
) -> Outcome:
    """Generate adaptors for `tds` (or the project configuration when `tds` is None) and write them.

    `Outcome.ok` is False with diagnostics when anything was invalid; then nothing was written.
    """
    options = dict(
        backends=backends,
        output=output,
        interfaces=interfaces,
        values=values,
        package_name=package_name,
        partial=partial,
        strict=strict,
    )
    targets, failed = _targets(tds, config, options)
    return failed or _generate(targets, force=force, use_cache=use_cache)


def check(
    tds: PathLike | Sequence[PathLike] | None = None,
    *,
    backends: Sequence[str] = ("all",),
    output: PathLike = "generated",
    interfaces: Sequence[PathLike] = (),
    values: Mapping[str, Any] | None = None,
    package_name: str | None = None,
    partial: bool = False,
    strict: bool = False,
    config: PathLike | None = None,
    use_cache: bool = True,
) -> Outcome:
    """Whether the generated code on disk is current (`Outcome.ok`); `Outcome.stale` lists what is not."""
    options = dict(
        backends=backends,
        output=output,
        interfaces=interfaces,
        values=values,
        package_name=package_name,
        partial=partial,
        strict=strict,
    )
    targets, failed = _targets(tds, config, options)
    return failed or _check(targets, use_cache=use_cache)
