"""The generation commands: gen and check (with TDs, or as the project configuration says)."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from td2adaptor.cli.common import (
    EXIT_INVALID,
    EXIT_OK,
    _format_option,
    _input_options,
    _label,
    _placeholder_values,
    cli,
    report,
)

if TYPE_CHECKING:
    from td2adaptor.diagnostics import Diagnostic, Diagnostics
    from td2adaptor.generation.targets import Target


#: errors about the output directory, not the input: refused overwrites, unsafe paths, failed writes
_OUTPUT_CODES = frozenset({"GEN801", "GEN802", "GEN806"})


def _backend_of(code: str) -> str | None:
    """The backend whose own code `code` is (`rclpy backend: ...` in the catalogue, or a backend's own stage)."""
    from td2adaptor.diagnostics.catalogue import lookup

    entry = lookup(code)
    if entry.stage.backend is not None:
        return entry.stage.backend
    first, _, rest = entry.meaning.partition(" ")
    return first if rest.startswith("backend") else None


def verdict_of(found: Sequence[Diagnostic], *, writes: bool = True) -> str | None:
    """What the verdict line says when the inputs are valid but nothing was generated: the output directory
    refused (an edited file, a failed write), or a backend cannot represent a valid TD (`gen -b mros` on a TD
    with services); None when there is no error or an input is invalid (the plain valid/invalid). `writes`:
    for gen (check never writes)."""
    refused = [d for d in found if d.severity.value == "error"]
    if not refused:
        return None
    if all(d.code in _OUTPUT_CODES for d in refused):  # the TDs are fine; the output directory is not
        return "valid, but nothing was written"
    backends = [_backend_of(d.code) for d in refused if d.code not in _OUTPUT_CODES]
    if None in backends:
        return None
    names = sorted(set(b for b in backends if b is not None))
    listed = " and ".join(names)
    return f"valid, but the {listed} backend{'s' * (len(names) > 1)} cannot generate it" + (
        ": nothing was written" if writes else ""
    )


def _parse_backend_options(
    _ctx: click.Context, param: click.Parameter, items: tuple[str, ...]
) -> tuple[tuple[str, Any], ...]:
    """`--option mros.sequence_capacity=64` items → (key, value) pairs; VALUE is JSON when it parses."""
    import json

    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise click.BadParameter(f"{item!r}: expected BACKEND.NAME=VALUE", param=param)
        try:
            out[key.strip()] = json.loads(raw)
        except ValueError:
            out[key.strip()] = raw
    return tuple(sorted(out.items()))


class _BackendOption(click.Option):
    """`--backend`, whose help names the backends found (a new backend folder shows up without an edit here);
    found only when the help is printed, since finding them imports every backend."""

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        from td2adaptor.backends.registry import modules

        self.help = f"{', '.join(modules())} or all (repeatable; default all)."
        return super().get_help_record(ctx)


def _gen_options(f: Any) -> Any:
    f = click.option("--backend", "-b", "backends", multiple=True, cls=_BackendOption)(f)
    f = click.option(
        "-o",
        "--output",
        type=click.Path(file_okay=False, path_type=Path),
        help="Output directory; each backend writes OUT/<backend>/ (default: generated).",
    )(f)
    f = click.option("--package-name", help="Override the ROS package name derived from the Thing title.")(f)
    f = click.option(
        "--partial",
        is_flag=True,
        help="Skip what a backend cannot express, and warn (mROS: one warning lists the skipped actions).",
    )(f)
    f = click.option(
        "--option",
        "backend_options",
        multiple=True,
        metavar="BACKEND.NAME=VALUE",
        callback=_parse_backend_options,
        help="A backend option, e.g. mros.sequence_capacity=64 (repeatable; JSON values are typed).",
    )(f)
    f = click.option(
        "--config",
        "config_file",
        type=click.Path(dir_okay=False, path_type=Path),
        help="Project configuration (default: td2adaptor.toml or [tool.td2adaptor] in pyproject.toml).",
    )(f)
    return f


def _targets(
    sources: Sequence[str],
    backends: Sequence[str],
    output: Path | None,
    package_name: str | None,
    partial: bool,
    interfaces: Sequence[Path],
    sets: Sequence[str],
    values_file: Path | None,
    strict: bool,
    config_file: Path | None,
    diags: Diagnostics,
    backend_options: tuple[tuple[str, Any], ...] = (),
) -> list[Target] | None:
    """Targets from the command line, or from the project configuration when no TD is given (the library
    API builds them with the same `targets`, so options override the configuration the same way)."""
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.generation.targets import NO_CONFIGURATION, Options, targets

    values, problems = _placeholder_values(sets, values_file)
    diags.extend(problems)
    if any(d.severity.value == "error" for d in problems):
        return None
    options = Options(
        backends=tuple(backends),
        output=output,
        interfaces=tuple(interfaces),
        values=tuple(sorted(values.items())),
        package_name=package_name,
        partial=partial,
        strict=strict,
        options=backend_options,
    )
    found = Diagnostics()
    result = targets(list(sources), options, found, config=config_file)
    if result is None and [d.code for d in found] == ["CFG907"]:
        raise click.UsageError(NO_CONFIGURATION)
    diags.extend(found)
    return result


@cli.command()
@click.argument("sources", nargs=-1, metavar="[TD]...")
@_gen_options
@click.option("--force", is_flag=True, help="Overwrite files that were edited by hand or not generated by td2adaptor.")
@click.option("--fail-on-change", is_flag=True, help="Exit 1 when any file was written or removed (for commit hooks).")
@_input_options
@_format_option
def gen(
    sources: tuple[str, ...],
    backends: tuple[str, ...],
    output: Path | None,
    package_name: str | None,
    partial: bool,
    backend_options: tuple[tuple[str, Any], ...],
    config_file: Path | None,
    force: bool,
    fail_on_change: bool,
    interfaces: tuple[Path, ...],
    sets: tuple[str, ...],
    values_file: Path | None,
    strict: bool,
    no_cache: bool,
    max_bytes: int,
    max_affordances: int,
    fmt: str,
) -> None:
    """Generate adaptor packages into OUT/<backend>/; with no TD, as configured for the project.

    Nothing is written when any input is invalid; unchanged files keep their mtime; files edited by hand
    are never overwritten without --force.
    """
    from td2adaptor.compiler.build import generate, resolve_backends
    from td2adaptor.diagnostics import Diagnostics

    _, problem = resolve_backends(backends)
    if problem:
        raise click.BadParameter(problem, param_hint="--backend")
    diags = Diagnostics()
    targets = _targets(
        sources,
        backends,
        output,
        package_name,
        partial,
        interfaces,
        sets,
        values_file,
        strict,
        config_file,
        diags,
        backend_options,
    )
    if targets is None:
        report(list(diags), fmt, label=_label(sources) or "configuration")
        sys.exit(EXIT_INVALID)
    from td2adaptor.support.gcpause import collector_paused

    with collector_paused():
        outcome = generate(targets, force=force, use_cache=not no_cache, parallel=True)
    label = _label(sources) or "configuration"
    found = [*diags, *outcome.diagnostics]
    ok = report(found, fmt, label=label, verdict=verdict_of(found)) and outcome.ok
    if fmt == "human":
        for root, rep in sorted(outcome.reports.items()):
            click.echo(
                f"{root}: {len(rep.written)} written, {len(rep.unchanged)} unchanged, {len(rep.removed)} removed",
                err=True,
            )
    changed = any(rep.written or rep.removed for rep in outcome.reports.values())
    if ok and fail_on_change and changed:
        click.echo("td2adaptor gen: generated files changed; review and add them", err=True)
        sys.exit(EXIT_INVALID)
    sys.exit(EXIT_OK if ok else EXIT_INVALID)


@cli.command()
@click.argument("sources", nargs=-1, metavar="[TD]...")
@_gen_options
@_input_options
@_format_option
def check(
    sources: tuple[str, ...],
    backends: tuple[str, ...],
    output: Path | None,
    package_name: str | None,
    partial: bool,
    backend_options: tuple[tuple[str, Any], ...],
    config_file: Path | None,
    interfaces: tuple[Path, ...],
    sets: tuple[str, ...],
    values_file: Path | None,
    strict: bool,
    no_cache: bool,
    max_bytes: int,
    max_affordances: int,
    fmt: str,
) -> None:
    """Regenerate in memory and compare with disk; never writes. Exit 1 when something is stale."""
    from td2adaptor.compiler.build import check as do_check
    from td2adaptor.diagnostics import Diagnostics

    diags = Diagnostics()
    targets = _targets(
        sources,
        backends,
        output,
        package_name,
        partial,
        interfaces,
        sets,
        values_file,
        strict,
        config_file,
        diags,
        backend_options,
    )
    if targets is None:
        report(list(diags), fmt, label=_label(sources) or "configuration")
        sys.exit(EXIT_INVALID)
    from td2adaptor.support.gcpause import collector_paused

    with collector_paused():
        outcome = do_check(targets, use_cache=not no_cache, parallel=True)
    # warnings belong to validate and gen; check reports only what makes it fail
    problems = [d for d in [*diags, *outcome.diagnostics] if d.severity.value == "error"]
    if fmt == "json":
        report(problems, fmt, label="check", extra={"current": outcome.ok, "stale": outcome.stale})
    else:
        if problems:
            report(problems, fmt, label=_label(sources) or "configuration", verdict=verdict_of(problems, writes=False))
        stale = outcome.stale
        for line in stale[:20]:
            click.echo(f"  {line}", err=True)
        if len(stale) > 20:
            click.echo(f"  ... and {len(stale) - 20} more", err=True)
        verdict = "current" if outcome.ok else f"stale ({len(stale)} file{'s' * (len(stale) != 1)})"
        click.echo(f"td2adaptor check: generated code is {verdict}", err=True)
    sys.exit(EXIT_OK if outcome.ok else EXIT_INVALID)
