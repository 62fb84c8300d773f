"""The front-end commands: validate, types, instantiate, migrate."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from td2adaptor.cli.common import (
    EXIT_INVALID,
    EXIT_OK,
    EXIT_USAGE,
    _compile_units,
    _format_option,
    _input_options,
    _label,
    _placeholder_values,
    cli,
    report,
    write_json,
)

# ---------------------------------------------------------------------------------------------------------
# commands


@cli.command()
@click.argument("sources", nargs=-1, required=True, metavar="TD...")
@_input_options
@_format_option
@click.option("--package-name", help="Override the ROS package name derived from the Thing title.")
def validate(
    sources: tuple[str, ...],
    interfaces: tuple[Path, ...],
    sets: tuple[str, ...],
    values_file: Path | None,
    strict: bool,
    no_cache: bool,
    max_bytes: int,
    max_affordances: int,
    fmt: str,
    package_name: str | None,
) -> None:
    """Validate TDs, Thing Models or legacy config files ('-' reads stdin) and resolve their ROS types.

    Several arguments are grouped as gen groups them: each TD alone, all RosClasses config files as one input.
    """
    from td2adaptor.support.gcpause import collector_paused

    with collector_paused():
        results = _compile_units(
            sources,
            interfaces,
            sets,
            values_file,
            strict,
            max_bytes,
            package_name,
            no_cache,
            max_affordances,
            need_model=False,  # only the diagnostics are reported
        )
    ok = report([d for result in results for d in result.diagnostics], fmt, label=_label(sources))
    sys.exit(EXIT_OK if ok else EXIT_INVALID)


@cli.command()
@click.argument("sources", nargs=-1, required=True, metavar="TD...")
@_input_options
@_format_option
def types(
    sources: tuple[str, ...],
    interfaces: tuple[Path, ...],
    sets: tuple[str, ...],
    values_file: Path | None,
    strict: bool,
    no_cache: bool,
    max_bytes: int,
    max_affordances: int,
    fmt: str,
) -> None:
    """Show components, their services, ROS actions and topics, and the resolved ROS types (one table per input).

    Several arguments are grouped as gen groups them: each TD alone, all RosClasses config files as one input.
    With --format json, `types` is one input's object, or a list of them for several inputs.
    """
    from td2adaptor.cli.typestable import types_json, types_text

    results = _compile_units(sources, interfaces, sets, values_file, strict, max_bytes, None, no_cache, max_affordances)
    diagnostics = [d for result in results for d in result.diagnostics]
    models = [result.model for result in results if result.model is not None]
    if len(models) < len(results):
        report(diagnostics, fmt, label=_label(sources))
        sys.exit(EXIT_INVALID)
    if fmt == "json":
        tables = [types_json(model) for model in models]
        report(diagnostics, fmt, label=_label(sources), extra={"types": tables[0] if len(tables) == 1 else tables})
    else:
        click.echo("\n".join(types_text(model) for model in models), nl=False)
        sys.stdout.flush()
        if diagnostics:
            report(diagnostics, fmt, label=_label(sources))
    sys.exit(EXIT_OK)


@cli.command()
@click.argument("model", metavar="TM")
@click.option("-o", "--output", required=True, help="Where to write the TD ('-' for stdout).")
@click.option("--set", "sets", multiple=True, metavar="NAME=VALUE", help="A placeholder value (repeatable).")
@click.option("--values", "values_file", type=click.Path(dir_okay=False, path_type=Path), help="JSON/YAML value map.")
@click.option(
    "--keep",
    multiple=True,
    default=("robotName",),
    show_default=True,
    help="Placeholders left in place when no value is given (runtime placeholders).",
)
@_format_option
def instantiate(
    model: str, output: str, sets: tuple[str, ...], values_file: Path | None, keep: tuple[str, ...], fmt: str
) -> None:
    """Instantiate a Thing Model into a Thing Description."""
    from td2adaptor.compiler.pipeline import _in_input_order
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.frontend.jsonsrc import load_path
    from td2adaptor.frontend.thingmodel import instantiate as do_instantiate
    from td2adaptor.frontend.thingmodel import is_thing_model

    values, problems = _placeholder_values(sets, values_file)
    diags = Diagnostics(problems)
    td = None
    if not diags.has_errors:
        doc = load_path(model, diags)
        if doc is not None:
            if not is_thing_model(doc.data):
                diags.error("TM300", "input is not a Thing Model (its @type lacks 'tm:ThingModel')", "/@type")
            else:
                from td2adaptor.frontend.conformance import check_tm

                local = Diagnostics()
                check_tm(doc, local)
                if not local.has_errors:
                    href = _relative_href(model, output)
                    td = do_instantiate(doc, values, local, keep=keep, model_href=href)
                diags.extend(doc.locate(d) for d in local)
    ok = report(_in_input_order(list(diags), None), fmt, label=model) and td is not None
    if not ok:
        sys.exit(EXIT_INVALID)
    write_json(td, output)
    sys.exit(EXIT_OK)


@cli.command()
@click.argument("sources", nargs=-1, required=True, metavar="IN...")
@click.option("-o", "--output", required=True, help="Where to write the TD ('-' for stdout).")
@click.option(
    "--interfaces",
    "-I",
    multiple=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder of interface packages; repeatable.",
)
@_format_option
def migrate(sources: tuple[str, ...], output: str, interfaces: tuple[Path, ...], fmt: str) -> None:
    """Convert a reference-dialect TD or legacy RosClasses config files into the td2adaptor binding."""
    from td2adaptor.compiler.pipeline import compile
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.frontend.migrate import migrate as do_migrate

    result = compile(list(sources), interfaces=list(interfaces))
    if result.model is None or result.input is None:
        report(result.diagnostics, fmt, label=_label(sources))
        sys.exit(EXIT_INVALID)
    notes = Diagnostics()
    assert result.input.td is not None  # a model was made from it
    td = do_migrate(result.input.td, result.model, notes, legacy=result.input.kind == "legacy")
    report([*result.diagnostics, *(result.input.doc.locate(d) for d in notes)], fmt, label=_label(sources))
    write_json(td, output)
    sys.exit(EXIT_OK)


def _relative_href(model: str, output: str) -> str | None:
    """The Thing Model as the TD's `rel: type` link should name it: relative to where the TD is written."""
    import os

    if model == "-":
        return None
    base = Path.cwd() if output == "-" else Path(output).resolve().parent
    return Path(os.path.relpath(Path(model).resolve(), base)).as_posix()


@cli.command()
@click.argument("codes", nargs=-1, required=True, metavar="CODE...")
@click.option("--format", "fmt", type=click.Choice(["human", "json"]), default="human", show_default=True)
def explain(codes: tuple[str, ...], fmt: str) -> None:
    """Show what diagnostic codes mean: severity, meaning, hint (all of them: docs/diagnostics.md)."""
    import json

    from td2adaptor.backends.registry import diagnostic_stages
    from td2adaptor.diagnostics.explain import explain_json, explain_text, unknown_codes

    diagnostic_stages()  # every installed backend's own codes join the catalogue
    unknown = unknown_codes(codes)
    if unknown:
        click.echo(f"unknown diagnostic code(s): {', '.join(unknown)} (all codes: docs/diagnostics.md)", err=True)
        sys.exit(EXIT_USAGE)
    click.echo(json.dumps(explain_json(codes), indent=2) if fmt == "json" else explain_text(codes))
    sys.exit(EXIT_OK)
