"""What every command shares: the `td2adaptor` click group, common options, compiling, reporting diagnostics.

Only click is imported at start-up; everything else loads on use. Exit codes: 0 valid (warnings allowed),
1 invalid input, 2 usage error, 3 internal error.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from td2adaptor import __version__

if TYPE_CHECKING:
    from td2adaptor.compiler.pipeline import Result
    from td2adaptor.diagnostics import Diagnostic

EXIT_OK, EXIT_INVALID, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 3

_COLOURS = {"error": "red", "warning": "yellow", "info": "cyan"}


def _print_version(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if value and not ctx.resilient_parsing:
        click.echo(f"td2adaptor {__version__}")
        ctx.exit(0)


class _Group(click.Group):
    """The group, whose usage errors never quote a URL's credentials: click echoes what it could not place
    (`Got unexpected extra argument (mqtt://edge:pw@host)` for a forgotten --bus), and the message ends up in
    terminals and logs like any other."""

    def make_context(
        self, info_name: str | None, args: list[str], parent: click.Context | None = None, **extra: Any
    ) -> click.Context:
        try:
            return super().make_context(info_name, args, parent, **extra)
        except click.ClickException as exc:
            raise _redacted(exc) from None

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except click.ClickException as exc:
            raise _redacted(exc) from None


def _redacted(exc: click.ClickException) -> click.ClickException:
    from td2adaptor.runtime.bus.security import redact_text

    said = exc.format_message()
    shown = redact_text(said)
    if shown == said:
        return exc
    if isinstance(exc, click.UsageError):  # keeps the usage line and exit code 2
        return click.UsageError(shown, exc.ctx)
    return click.ClickException(shown)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 110})
@click.option(
    "--version",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_print_version,
    help="Show the version.",
)
def cli() -> None:
    """Turn W3C WoT Thing Descriptions of robots into ROS adaptor packages."""


# ---------------------------------------------------------------------------------------------------------
# shared options


def _input_options(f: Any) -> Any:
    f = click.option(
        "--max-bytes",
        type=click.IntRange(min=1),
        default=16 * 1024 * 1024,
        show_default=True,
        help="Refuse inputs larger than this.",
    )(f)
    f = click.option(
        "--max-affordances",
        type=click.IntRange(min=1),
        default=20_000,
        show_default=True,
        help="Refuse TDs with more affordances than this.",
    )(f)
    f = click.option("--strict", is_flag=True, help="Treat warnings as errors.")(f)
    f = click.option("--no-cache", is_flag=True, help="Recompile even if the result cache has this input.")(f)
    f = click.option(
        "--values",
        "values_file",
        type=click.Path(dir_okay=False, path_type=Path),
        help="JSON or YAML map of Thing Model placeholder values.",
    )(f)
    f = click.option(
        "--set",
        "sets",
        multiple=True,
        metavar="NAME=VALUE",
        help="A Thing Model placeholder value (repeatable; JSON values are typed).",
    )(f)
    f = click.option(
        "--interfaces",
        "-I",
        multiple=True,
        type=click.Path(file_okay=False, path_type=Path),
        help="Folder of interface packages (pkg/msg/*.msg, pkg/srv/*.srv, pkg/action/*.action); repeatable.",
    )(f)
    return f


def _format_option(f: Any) -> Any:
    return click.option(
        "--format",
        "fmt",
        type=click.Choice(["human", "json"]),
        default="human",
        show_default=True,
        help="Diagnostics as text or as JSON on stdout.",
    )(f)


def _placeholder_values(sets: Sequence[str], values_file: Path | None) -> tuple[dict[str, Any], list[Diagnostic]]:
    if not sets and values_file is None:
        return {}, []  # nothing to parse: the Thing Model code stays unloaded (start-up time)
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.frontend.thingmodel import load_placeholder_map, parse_set_options

    diags = Diagnostics()
    values: dict[str, Any] = {}
    if values_file is not None:
        loaded = load_placeholder_map(values_file, diags)
        values.update(loaded or {})
    values.update(parse_set_options(list(sets), diags))
    return values, list(diags)


def _compile(
    sources: Sequence[str],
    interfaces: Sequence[Path],
    sets: Sequence[str],
    values_file: Path | None,
    strict: bool,
    max_bytes: int,
    package: str | None = None,
    no_cache: bool = False,
    max_affordances: int = 20_000,
) -> Result:
    """Compile `sources` as one input (one TD, or RosClasses config files)."""
    return _compile_units(
        sources,
        interfaces,
        sets,
        values_file,
        strict,
        max_bytes,
        package,
        no_cache,
        max_affordances,
        units=[list(sources)],
    )[0]


def _compile_units(
    sources: Sequence[str],
    interfaces: Sequence[Path],
    sets: Sequence[str],
    values_file: Path | None,
    strict: bool,
    max_bytes: int,
    package: str | None = None,
    no_cache: bool = False,
    max_affordances: int = 20_000,
    *,
    units: Sequence[Sequence[str]] | None = None,
    need_model: bool = True,
) -> list[Result]:
    """One Result per input that `sources` make, grouped as gen and check group them (`_units`); problems with
    --set/--values come once, with the first. Never empty. Without `need_model`, a result-cache hit leaves
    `model` None (see `compile`)."""
    from td2adaptor.compiler.pipeline import Result, compile

    values, problems = _placeholder_values(sets, values_file)
    if any(d.severity.value == "error" for d in problems):
        return [Result(None, tuple(problems))]
    results: list[Result] = []
    for unit in _units(sources) if units is None else units:
        result = compile(
            list(unit),
            interfaces=list(interfaces),
            values=values,
            strict=strict,
            package=package,
            max_bytes=max_bytes,
            max_affordances=max_affordances,
            use_cache=not no_cache,
            parallel=True,
            need_model=need_model,
        )
        before = () if results else tuple(problems)
        results.append(Result(result.model, before + result.diagnostics, result.input))
    return results


def _units(sources: Sequence[str]) -> list[list[str]]:
    """The inputs `sources` make, as `compiler.units.compile_units` groups a target's files: every RosClasses
    config file together, each TD alone. Spelled as given; stdin ('-') can be read only once, so arguments
    with it stay one input."""
    if len(sources) < 2 or "-" in sources:
        return [list(sources)]
    from td2adaptor.compiler.units import compile_units

    paths = [Path(s) for s in sources]
    spelled = {id(p): s for p, s in zip(paths, sources, strict=True)}
    return [[spelled[id(p)] for p in unit] for unit in compile_units(paths)]


def report(
    diagnostics: Sequence[Diagnostic],
    fmt: str,
    *,
    label: str,
    extra: dict[str, Any] | None = None,
    counted: Sequence[Diagnostic] | None = None,
    verdict: str | None = None,
) -> bool:
    """Print diagnostics (stderr for humans, stdout JSON); True when there is no error.

    `counted`: the diagnostics the verdict line counts, when only some of them are printed; `verdict`: what
    to say instead of valid/invalid (when the input was fine and something else went wrong: JSON then says
    `valid` true, with the `verdict`)."""
    total = diagnostics if counted is None else counted
    errors = sum(d.severity.value == "error" for d in total)
    warnings = sum(d.severity.value == "warning" for d in total)
    if fmt == "json":
        doc: dict[str, Any] = {"valid": errors == 0 or verdict is not None, "errors": errors, "warnings": warnings}
        if verdict is not None:
            doc["verdict"] = verdict
        doc.update(extra or {})
        doc["diagnostics"] = [d.to_json() for d in diagnostics]
        click.echo(json.dumps(doc, indent=2, ensure_ascii=False))
        return errors == 0
    for d in diagnostics:
        sev = click.style(d.severity.value, fg=_COLOURS[d.severity.value], bold=True)
        where = f" at {d.pointer}" if d.pointer else ""
        click.echo(f"{d.location}: {sev} {d.code}: {d.message}{where}", err=True)
        if d.hint:
            click.echo(f"    hint: {d.hint}", err=True)
    if verdict is not None:
        verdict = click.style(verdict, fg="red", bold=True)
    else:
        verdict = click.style("valid", fg="green") if errors == 0 else click.style("invalid", fg="red", bold=True)
    click.echo(
        f"{label}: {verdict} ({errors} error{'s' * (errors != 1)}, {warnings} warning{'s' * (warnings != 1)})",
        err=True,
    )
    return errors == 0


def _positive(_ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not value > 0:
        raise click.BadParameter("must be a positive number of seconds", param=param)
    return value


def _fail(command: str, message: str) -> Any:
    click.echo(f"td2adaptor {command}: {message}", err=True)
    sys.exit(EXIT_INVALID)


def _label(sources: Sequence[str]) -> str:
    return ", ".join("<stdin>" if s == "-" else s for s in sources)


def write_json(data: Any, output: str) -> None:
    """Write JSON to a file atomically (temp file + rename), or to stdout for '-'."""
    text = json.dumps(data, indent=2, ensure_ascii=False) + "\n"
    if output == "-":
        click.echo(text, nl=False)
        return
    from td2adaptor.support.fsutil import write_atomic

    write_atomic(Path(output), text.encode("utf-8"))
