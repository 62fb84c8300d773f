"""The `td2adaptor` command line. Only click is imported at start-up; everything else loads on use.

Exit codes: 0 valid (warnings allowed), 1 invalid input, 2 usage error, 3 internal error.
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


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 110})
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
        help="Folder of interface packages (pkg/msg/*.msg, pkg/srv/*.srv); repeatable.",
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
    from td2adaptor.compiler.pipeline import Result, compile

    values, problems = _placeholder_values(sets, values_file)
    if any(d.severity.value == "error" for d in problems):
        return Result(None, tuple(problems))
    result = compile(
        list(sources),
        interfaces=list(interfaces),
        values=values,
        strict=strict,
        package=package,
        max_bytes=max_bytes,
        max_affordances=max_affordances,
        use_cache=not no_cache,
        parallel=True,
    )
    return Result(result.model, tuple(problems) + result.diagnostics, result.input)


def report(diagnostics: Sequence[Diagnostic], fmt: str, *, label: str, extra: dict[str, Any] | None = None) -> bool:
    """Print diagnostics (stderr for humans, stdout JSON); True when there is no error."""
    errors = sum(d.severity.value == "error" for d in diagnostics)
    warnings = sum(d.severity.value == "warning" for d in diagnostics)
    if fmt == "json":
        doc: dict[str, Any] = {"valid": errors == 0, "errors": errors, "warnings": warnings}
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
    verdict = click.style("valid", fg="green") if errors == 0 else click.style("invalid", fg="red", bold=True)
    click.echo(
        f"{label}: {verdict} ({errors} error{'s' * (errors != 1)}, {warnings} warning{'s' * (warnings != 1)})",
        err=True,
    )
    return errors == 0


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
    """Validate a TD, Thing Model or legacy config ('-' reads stdin) and resolve its ROS types."""
    result = _compile(
        sources, interfaces, sets, values_file, strict, max_bytes, package_name, no_cache, max_affordances
    )
    ok = report(result.diagnostics, fmt, label=_label(sources))
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
    """Show components, their services and topics, and the resolved ROS types."""
    from td2adaptor.cli.typestable import types_json, types_text

    result = _compile(sources, interfaces, sets, values_file, strict, max_bytes, None, no_cache, max_affordances)
    if result.model is None:
        report(result.diagnostics, fmt, label=_label(sources))
        sys.exit(EXIT_INVALID)
    if fmt == "json":
        report(result.diagnostics, fmt, label=_label(sources), extra={"types": types_json(result.model)})
    else:
        click.echo(types_text(result.model), nl=False)
        sys.stdout.flush()
        if result.diagnostics:
            report(result.diagnostics, fmt, label=_label(sources))
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
    td = do_migrate(result.input, result.model, notes)
    report([*result.diagnostics, *(result.input.doc.locate(d) for d in notes)], fmt, label=_label(sources))
    write_json(td, output)
    sys.exit(EXIT_OK)


def _gen_options(f: Any) -> Any:
    f = click.option(
        "--backend",
        "-b",
        "backends",
        multiple=True,
        help="rclpy, rospy, mros, events or all (repeatable; default all).",
    )(f)
    f = click.option(
        "-o",
        "--output",
        type=click.Path(file_okay=False, path_type=Path),
        help="Output directory; each backend writes OUT/<backend>/ (default: generated).",
    )(f)
    f = click.option("--package-name", help="Override the ROS package name derived from the Thing title.")(f)
    f = click.option("--partial", is_flag=True, help="Skip what a backend cannot express, with a warning each.")(f)
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
    diags: Any,
) -> list[Any] | None:
    """Targets from the command line, or from the project configuration when no TD is given."""
    from td2adaptor.generation import targets as config
    from td2adaptor.generation.build import target

    if sources:
        values, problems = _placeholder_values(sets, values_file)
        diags.extend(problems)
        if any(d.severity.value == "error" for d in problems):
            return None
        return [
            target(
                list(sources),
                backends=list(backends) or ["all"],
                output=output or Path("generated"),
                interfaces=list(interfaces),
                values=values,
                package_name=package_name,
                partial=partial,
                strict=strict,
            )
        ]
    path = config_file or config.find()
    if path is None:
        raise click.UsageError("no TD given and no td2adaptor.toml or [tool.td2adaptor] in pyproject.toml found")
    loaded = config.load(path, diags)
    if loaded is None:
        return None
    from dataclasses import replace

    out = []
    for t in loaded.targets:
        changes: dict[str, Any] = {}
        if backends:
            changes["backends"] = tuple(backends)
        if output is not None:
            changes["output"] = output
        if partial:
            changes["partial"] = True
        if strict:
            changes["strict"] = True
        out.append(replace(t, **changes))
    return out


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
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.generation.build import generate, resolve_backends

    _, problem = resolve_backends(backends)
    if problem:
        raise click.BadParameter(problem, param_hint="--backend")
    diags = Diagnostics()
    targets = _targets(
        sources, backends, output, package_name, partial, interfaces, sets, values_file, strict, config_file, diags
    )
    if targets is None:
        report(list(diags), fmt, label=_label(sources) or "configuration")
        sys.exit(EXIT_INVALID)
    outcome = generate(targets, force=force, use_cache=not no_cache, parallel=True)
    label = _label(sources) or "configuration"
    ok = report([*diags, *outcome.diagnostics], fmt, label=label) and outcome.ok
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
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.generation.build import check as do_check

    diags = Diagnostics()
    targets = _targets(
        sources, backends, output, package_name, partial, interfaces, sets, values_file, strict, config_file, diags
    )
    if targets is None:
        report(list(diags), fmt, label=_label(sources) or "configuration")
        sys.exit(EXIT_INVALID)
    outcome = do_check(targets, use_cache=not no_cache, parallel=True)
    # warnings belong to validate and gen; check reports only what makes it fail
    problems = [d for d in [*diags, *outcome.diagnostics] if d.severity.value == "error"]
    if fmt == "json":
        report(problems, fmt, label="check", extra={"current": outcome.ok, "stale": outcome.stale})
    else:
        if problems:
            report(problems, fmt, label=_label(sources) or "configuration")
        stale = outcome.stale
        for line in stale[:20]:
            click.echo(f"  {line}", err=True)
        if len(stale) > 20:
            click.echo(f"  ... and {len(stale) - 20} more", err=True)
        verdict = "current" if outcome.ok else f"stale ({len(stale)} file{'s' * (len(stale) != 1)})"
        click.echo(f"td2adaptor check: generated code is {verdict}", err=True)
    sys.exit(EXIT_OK if outcome.ok else EXIT_INVALID)


@cli.command()
@click.argument("codes", nargs=-1, required=True, metavar="CODE...")
@click.option("--format", "fmt", type=click.Choice(["human", "json"]), default="human", show_default=True)
def explain(codes: tuple[str, ...], fmt: str) -> None:
    """Show what diagnostic codes mean: severity, meaning, hint (all of them: docs/diagnostics.md)."""
    from td2adaptor.diagnostics.explain import explain_json, explain_text, unknown_codes

    unknown = unknown_codes(codes)
    if unknown:
        click.echo(f"unknown diagnostic code(s): {', '.join(unknown)} (all codes: docs/diagnostics.md)", err=True)
        sys.exit(EXIT_USAGE)
    click.echo(json.dumps(explain_json(codes), indent=2) if fmt == "json" else explain_text(codes))
    sys.exit(EXIT_OK)


# ---------------------------------------------------------------------------------------------------------
# the edge node and the demo


def _positive(_ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not value > 0:
        raise click.BadParameter("must be a positive number of seconds", param=param)
    return value


@cli.command()
@click.argument("source", metavar="TD")
@_input_options
@click.option("--robot", help="Robot id on the bus (default: TD2ADAPTOR_ROBOT or the configuration file).")
@click.option("--namespace", help="ROS namespace of the robot ({{robotName}}); default: the robot id.")
@click.option("--bus", help="mqtt://host:port, mqtts://host:port or local (default: local).")
@click.option(
    "--config",
    "config_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="YAML runtime configuration; with a robots: list, one process serves the whole fleet.",
)
@click.option("--ros", type=click.Choice(["1", "2"]), default="2", show_default=True, help="ROS version.")
@click.option("--package", help="Module name of the generated adaptor package (default: the TD's package name).")
@click.option(
    "--package-path",
    "package_paths",
    multiple=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Directory to import the adaptor (and ROS 1 interfaces) from, e.g. the generated source; repeatable.",
)
@click.option(
    "--prefix",
    "prefixes",
    multiple=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="ROS 2 install prefix to load (built interfaces, a colcon install space); repeatable.",
)
@click.option("--ros1-python", help="Interpreter that has rospy (ROS 1 runs in a bridge process under it).")
@click.option("--domain-id", type=click.IntRange(0, 232), help="ROS 2 domain id (default: ROS_DOMAIN_ID).")
@click.option("--master-uri", help="ROS 1 master URI (default: ROS_MASTER_URI).")
@click.option("--poll-period", type=float, callback=_positive, help="Seconds between queries of a mission.")
@click.option("--mission-timeout", type=float, callback=_positive, help="Overall limit of one mission, seconds.")
@click.option("--call-timeout", type=float, callback=_positive, help="Limit of one ROS call, seconds.")
@click.option("--property-period", type=float, help="Seconds between property events (0: none).")
@click.option("--allow-insecure", is_flag=True, default=None, help="Allow nosec/plain connections to remote brokers.")
@click.option(
    "--log-level",
    type=click.Choice(["debug", "info", "warning", "error"]),
    default="info",
    show_default=True,
    help="What the edge node logs (stderr).",
)
def run(
    source: str,
    interfaces: tuple[Path, ...],
    sets: tuple[str, ...],
    values_file: Path | None,
    strict: bool,
    no_cache: bool,
    max_bytes: int,
    max_affordances: int,
    robot: str | None,
    namespace: str | None,
    bus: str | None,
    config_file: Path | None,
    ros: str,
    package: str | None,
    package_paths: tuple[Path, ...],
    prefixes: tuple[Path, ...],
    ros1_python: str | None,
    domain_id: int | None,
    master_uri: str | None,
    poll_period: float | None,
    mission_timeout: float | None,
    call_timeout: float | None,
    property_period: float | None,
    allow_insecure: bool | None,
    log_level: str,
) -> None:
    """Run the edge node of a robot (or a fleet): bus events in, ROS calls out, feedback back.

    The generated adaptor package must be importable: source the colcon/catkin install space it was built
    into, or give --package-path (its source directory) and, for ROS 2, --prefix (the built interfaces).
    Precedence of settings: options > TD2ADAPTOR_* environment > --config file. SIGINT/SIGTERM stop it
    cleanly (the robot's status becomes offline).
    """
    import logging
    import signal
    import threading

    from td2adaptor.runtime.node import EdgeNode, RosOptions, wait_for_signal

    stop = threading.Event()
    result = _compile([source], interfaces, sets, values_file, strict, max_bytes, None, no_cache, max_affordances)
    if result.model is None:
        report(result.diagnostics, "human", label=_label([source]))
        sys.exit(EXIT_INVALID)
    if result.diagnostics:
        report(result.diagnostics, "human", label=_label([source]))
    from td2adaptor.runtime.config import ConfigError, load_fleet

    overrides: dict[str, Any] = {
        "robot": robot,
        "namespace": namespace,
        "bus": bus,
        "ros_domain_id": domain_id,
        "ros_master_uri": master_uri,
        "poll_period": poll_period,
        "mission_timeout": mission_timeout,
        "call_timeout": call_timeout,
        "property_period": property_period,
        "allow_insecure": allow_insecure,
    }
    try:
        configs = load_fleet(config_file, overrides=overrides)
    except ConfigError as exc:
        _fail("run", f"configuration: {exc}")
    logging.basicConfig(
        level=getattr(logging, log_level.upper()), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    if any(c.bus == "local" for c in configs):
        click.echo(
            "td2adaptor run: warning: --bus local is in-process; nothing outside this process can reach it", err=True
        )
    from td2adaptor.runtime.bus import BusError
    from td2adaptor.runtime.port import PortError
    from td2adaptor.runtime.ros import RosSetupError
    from td2adaptor.runtime.security import SecurityError

    options = RosOptions(int(ros), package, package_paths, prefixes, ros1_python)
    node = EdgeNode(result.model, configs, options)

    def interrupt(_signum: int, _frame: Any) -> None:
        raise KeyboardInterrupt  # SIGTERM while starting: undo what was opened, like Ctrl-C

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        node.start()
    except KeyboardInterrupt:
        node.stop()
        click.echo("td2adaptor run: interrupted while starting", err=True)
        sys.exit(130)
    except (RosSetupError, SecurityError, BusError, PortError) as exc:  # the user's to fix: one clear line
        node.stop()
        _fail("run", str(exc))
    finally:
        signal.signal(signal.SIGTERM, previous)
    click.echo(f"td2adaptor run: {node.describe()}; SIGINT/SIGTERM stops", err=True)
    try:
        wait_for_signal(stop)
    finally:
        node.stop()
        click.echo("td2adaptor run: stopped", err=True)
    sys.exit(EXIT_OK)


def _fail(command: str, message: str) -> Any:
    click.echo(f"td2adaptor {command}: {message}", err=True)
    sys.exit(EXIT_INVALID)


@cli.group()
def demo() -> None:
    """Demonstrations that run on a simulated robot (from a source checkout)."""


@demo.command()
@click.option("--bus", default="local", show_default=True, help="local, or mqtt://host:port of a running broker.")
@click.option("--robots", type=click.IntRange(1, 3), default=3, show_default=True, help="How many robots.")
@click.option(
    "--duration",
    type=float,
    default=1.0,
    show_default=True,
    callback=_positive,
    help="Seconds each simulated procedure takes.",
)
@click.option(
    "--timeout", type=float, default=120.0, show_default=True, callback=_positive, help="Give up after this long."
)
@click.option(
    "--cache",
    "cache_dir",
    type=click.Path(file_okay=False, path_type=Path),
    help="Where the built ROS 2 interfaces are kept (default: .cache/ros2-interfaces of the checkout).",
)
@click.option("--allow-insecure", is_flag=True, help="Allow a broker that is not on this machine.")
@click.option("-v", "--verbose", is_flag=True, help="Log what the edge nodes do.")
def warehouse(
    bus: str, robots: int, duration: float, timeout: float, cache_dir: Path | None, allow_insecure: bool, verbose: bool
) -> None:
    """Three RB-1s move three carts through a door into storage zones A/B/C (ROS 2 Jazzy, simulated).

    A behaviour service that talks only events over the bus takes carts from a shared SQLite task table and
    drives the robots through their edge nodes; with --bus mqtt://... every edge node is its own process.
    Prints a summary (carts moved, bus messages per action, total time); exit 0 when every cart is stored.
    """
    demo_module = _checkout_module("examples.warehouse.warehouse")
    if demo_module is None:
        _fail(
            "demo warehouse",
            "the demo runs from a source checkout of td2adaptor (it needs examples/: the RB-1 robot, its "
            "simulation and the warehouse); this installation has none",
        )
    DemoError, WarehouseOptions, run_warehouse = (
        demo_module.DemoError,
        demo_module.WarehouseOptions,
        demo_module.run_warehouse,
    )
    options = WarehouseOptions(
        bus=bus,
        robots=robots,
        duration=duration,
        timeout=timeout,
        cache_dir=cache_dir,
        allow_insecure=allow_insecure,
        verbose=verbose,
    )
    try:
        ok = run_warehouse(options)
    except DemoError as exc:
        _fail("demo warehouse", str(exc))
    sys.exit(EXIT_OK if ok else EXIT_INVALID)


def _checkout_module(name: str) -> Any:
    """A module of the source checkout this td2adaptor runs from (examples/ is not part of the wheel)."""
    import importlib

    repo = Path(__file__).resolve().parents[2]
    if not (repo / "examples" / "warehouse" / "warehouse.py").is_file():
        return None
    if str(repo) not in sys.path:
        sys.path.insert(0, str(repo))
    return importlib.import_module(name)


def _relative_href(model: str, output: str) -> str | None:
    """The Thing Model as the TD's `rel: type` link should name it: relative to where the TD is written."""
    import os

    if model == "-":
        return None
    base = Path.cwd() if output == "-" else Path(output).resolve().parent
    return Path(os.path.relpath(Path(model).resolve(), base)).as_posix()


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


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point: bad input never ends in a traceback."""
    try:
        cli.main(args=list(argv) if argv is not None else None, prog_name="td2adaptor", standalone_mode=True)
    except SystemExit:
        raise
    except KeyboardInterrupt:
        click.echo("td2adaptor: interrupted", err=True)
        sys.exit(130)
    except Exception as exc:  # noqa: BLE001 - the one place that turns bugs into a clean exit 3
        click.echo(f"td2adaptor: internal error: {type(exc).__name__}: {exc} (please report this)", err=True)
        sys.exit(EXIT_INTERNAL)


if __name__ == "__main__":
    main()
