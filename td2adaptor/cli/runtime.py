"""The edge node (`run`), a robot's Thing Description (`expose`) and the demonstrations (`demo warehouse`, from a
source checkout)."""

from __future__ import annotations

import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from td2adaptor.cli.common import (
    EXIT_INVALID,
    EXIT_OK,
    _compile,
    _fail,
    _input_options,
    _label,
    _positive,
    cli,
    report,
)

if TYPE_CHECKING:
    from td2adaptor.diagnostics import Diagnostic

# ---------------------------------------------------------------------------------------------------------
# the edge node and the demo


@cli.command()
@click.argument("source", metavar="TD")
@_input_options
@click.option("--robot", help="Robot id on the bus (default: TD2ADAPTOR_ROBOT or the configuration file).")
@click.option("--namespace", help="ROS namespace of the robot ({{robotName}}); default: the robot id.")
@click.option("--bus", help="mqtt://host:port, mqtts://host:port or local (default: local).")
@click.option(
    "--mqtt-version",
    type=click.Choice(["5", "3.1.1"]),
    help="MQTT protocol version to speak to the broker (default: 5; 3.1.1 for brokers that speak only that).",
)
@click.option(
    "--broker",
    help="Broker URL the robot's published Thing Description names (default: the --bus URL; with a local bus, "
    "no TD is published).",
)
@click.option(
    "--directory",
    help="W3C WoT Thing Description Directory (http(s)://host:port[/path]) to register each robot's TD with "
    "while it runs (PUT /things/{id}, DELETE on stop); token: TD2ADAPTOR_DIRECTORY_TOKEN.",
)
@click.option(
    "--directory-ttl",
    type=click.IntRange(min=0),
    help="Seconds the directory keeps a TD without a refresh (default 600; refreshed every ttl/2; 0: no expiry).",
)
@click.option(
    "--config",
    "config_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="YAML runtime configuration; with a robots: list, one process serves the whole fleet.",
)
@click.option(
    "--discover",
    is_flag=True,
    help="Serve every robot whose namespace shows the Thing Model's ROS interfaces in the ROS graph (ROS 2, or "
    "the ROS 1 master), from when it appears until it has been gone for --discover-grace.",
)
@click.option(
    "--discover-grace",
    type=click.FloatRange(min=0),
    help="Seconds a discovered robot may be gone from the ROS graph before it is retired (default 10).",
)
@click.option(
    "--share",
    is_flag=True,
    default=None,
    help="Share the fleet's robots (the fleet file's, with --discover those the ROS graph shows, and those admin "
    "requests add) with the other processes run with --share on the same broker and fleet: each robot is served by "
    "one of the processes that list it, each takes a fair share, and a dead one's robots are taken over "
    "(docs/fleet.md, 'Several processes share a fleet').",
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
    "--allow-anonymous-broker",
    is_flag=True,
    default=None,
    help="Run although the TD requires authentication and the broker accepts anonymous clients.",
)
@click.option(
    "--log-level",
    type=click.Choice(["debug", "info", "warning", "error"]),
    default="info",
    show_default=True,
    help="What the edge node logs (stderr).",
)
@click.option(
    "--metrics",
    envvar="TD2ADAPTOR_METRICS",
    metavar="HOST:PORT",
    help="Serve Prometheus metrics over HTTP on this address, e.g. 127.0.0.1:9464; port 0 takes a free one, "
    "named on the start line (default: none).",
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
    mqtt_version: str | None,
    broker: str | None,
    directory: str | None,
    directory_ttl: int | None,
    config_file: Path | None,
    discover: bool,
    discover_grace: float | None,
    share: bool | None,
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
    allow_anonymous_broker: bool | None,
    log_level: str,
    metrics: str | None,
) -> None:
    """Run the edge node of a robot (or a fleet): bus events in, ROS calls out, feedback back.

    The generated adaptor package must be importable: source the colcon/catkin install space it was built
    into, or give --package-path (its source directory) and, for ROS 2, --prefix (the built interfaces).
    Precedence of settings: options > TD2ADAPTOR_* environment > --config file. Once online, each robot's
    Thing Description (what `td2adaptor expose` writes) is retained on td2adaptor/<robot>/td and, with
    --directory, registered with a TD directory. SIGINT/SIGTERM stop it cleanly (the TD is cleared and
    deregistered, the robot's status becomes offline). When the TD requires authentication, a broker that
    accepts anonymous clients is refused at start and on every reconnection: the node stops and exits 1.
    Robots join and leave while it runs: the --config file is read again on SIGHUP and when it changes on
    disk, --discover follows the ROS graph, and admin requests on the bus add or remove one (docs/fleet.md).
    With --share the processes of one fleet share all of these robots: each is served by one process that
    lists it (its file, the robots its graph shows, the admin's), and a dead process's robots are taken over.
    """
    import logging
    import signal

    from td2adaptor.runtime.node.node import EdgeNode, RosOptions, wait_for_signal

    result = _compile([source], interfaces, sets, values_file, strict, max_bytes, None, no_cache, max_affordances)
    if result.model is None:
        report(result.diagnostics, "human", label=_label([source]))
        sys.exit(EXIT_INVALID)
    if result.diagnostics:
        given = [*(a for folder in interfaces for a in ("-I", str(folder))), *(a for v in sets for a in ("--set", v))]
        given += ["--values", str(values_file)] if values_file is not None else []
        _summarise(result.diagnostics, source, given)
    from td2adaptor.runtime.config import ConfigError, load_fleet

    overrides: dict[str, Any] = {
        "robot": robot,
        "namespace": namespace,
        "bus": bus,
        "mqtt_version": mqtt_version,
        "td_broker": broker,
        "directory": directory,
        "directory_ttl": directory_ttl,
        "ros_domain_id": domain_id,
        "ros_master_uri": master_uri,
        "poll_period": poll_period,
        "mission_timeout": mission_timeout,
        "call_timeout": call_timeout,
        "property_period": property_period,
        "allow_insecure": allow_insecure,
        "allow_anonymous_broker": allow_anonymous_broker,
        "discover_grace": discover_grace,
        "share": share,
    }
    from td2adaptor.runtime.config import load_defaults, names_robots
    from td2adaptor.runtime.node.fleetfile import stamp

    seen = stamp(config_file) if config_file is not None else None  # before it is read: a change meanwhile counts

    def load() -> list[Any]:
        if discover and not robot and not names_robots(config_file):
            # only the robots discovery finds; the file's settings checked all the same: a reading of a broken
            # file (a YAML error, `poll_period: -1`) said "reloaded: no change" instead of "not reloaded: <why>"
            load_defaults(config_file, overrides=overrides)
            return []
        return load_fleet(config_file, overrides=overrides)

    try:
        configs = load()
        defaults = load_defaults(config_file, overrides=overrides)
        if discover:
            from td2adaptor.runtime.node.graphwatch import signature

            signature(result.model)
    except ConfigError as exc:
        _fail("run", f"configuration: {exc}")
    shared = bool(defaults.get("share"))
    if shared and (defaults.get("bus", "local") == "local" or any(c.bus != defaults.get("bus") for c in configs)):
        _fail("run", "--share needs one MQTT bus for the whole fleet: the processes that share it meet on its broker")
    logging.basicConfig(
        level=getattr(logging, log_level.upper()), format="%(asctime)s %(levelname)s %(name)s: %(message)s"
    )
    if defaults.get("bus", "local") == "local" or any(c.bus == "local" for c in configs):
        click.echo(
            "td2adaptor run: warning: --bus local is in-process; nothing outside this process can reach it", err=True
        )
    from td2adaptor.runtime.bus.bus import BusError
    from td2adaptor.runtime.bus.security import SecurityError
    from td2adaptor.runtime.node.metrics import MetricsError
    from td2adaptor.runtime.ros.port import PortError, RosSetupError, StalePackage

    options = RosOptions(int(ros), package, package_paths, prefixes, ros1_python)
    node = EdgeNode(result.model, [] if shared else configs, options, defaults=defaults, metrics=metrics)

    def interrupt(_signum: int, _frame: Any) -> None:
        raise KeyboardInterrupt  # SIGTERM while starting: undo what was opened, like Ctrl-C

    previous = signal.signal(signal.SIGTERM, interrupt)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)  # until the main loop takes it: the file is looked at afterwards
    try:
        node.start()
        if shared:  # before discovery and admin requests: they change the shared fleet then
            node.share(configs)
        if discover:
            node.discover()
        if defaults.get("bus", "local") != "local":
            try:
                node.listen_admin()
            except (SecurityError, BusError) as exc:  # the robots are served all the same
                click.echo(f"td2adaptor run: warning: admin requests are not taken: {exc}", err=True)
    except KeyboardInterrupt:
        node.stop()
        click.echo("td2adaptor run: interrupted while starting", err=True)
        sys.exit(130)
    except StalePackage as exc:  # generated from another TD: say the command that makes it again
        node.stop()
        backend = "rospy" if exc.distro == "ros1" else "rclpy"
        given = [*(a for folder in interfaces for a in ("-I", str(folder))), *(a for v in sets for a in ("--set", v))]
        given += ["--values", str(values_file)] if values_file is not None else []
        given += ["--package-name", exc.package] if exc.package != result.model.package_name else []
        command = shlex.join(["td2adaptor", "gen", source, "-b", backend, *given])
        _fail("run", f"{exc}; regenerate it with `{command} -o DIR` (DIR: where it is kept) and build it again")
    except (RosSetupError, SecurityError, BusError, PortError, MetricsError) as exc:  # the user's to fix: one line
        node.stop()
        _fail("run", str(exc))  # a robot another process serves too (OwnerConflict): exit 1, saying which
    finally:
        signal.signal(signal.SIGTERM, previous)
    from td2adaptor.support.gcpause import freeze_startup

    freeze_startup()  # the collector's full passes no longer walk what starting made (every robot's engine)
    watched = None
    if config_file is not None and node.fleet is not None:
        from td2adaptor.runtime.node.fleetfile import FleetFile

        watched = FleetFile(config_file, node.shared or node.fleet, load, seen=seen)
    reloads = "; SIGHUP or a change of the file reloads it" if watched is not None else ""
    click.echo(f"td2adaptor run: {node.describe()}{reloads}; SIGINT/SIGTERM stops", err=True)
    try:
        wait_for_signal(  # or until a robot's broker fails the check on reconnecting
            node.halted,
            reload=None if watched is None else watched.reload,
            tick=None if watched is None else watched.poll,
            period=0.25,  # a look at the file: one stat
        )
    finally:
        node.stop()
        click.echo("td2adaptor run: stopped", err=True)
    if node.failure is not None:
        _fail("run", node.failure)
    sys.exit(EXIT_OK)


@cli.command()
@click.argument("source", metavar="TD")
@_input_options
@click.option("--robot", required=True, help="Robot id on the bus (as `run --robot`).")
@click.option("--broker", required=True, help="mqtt://host:port or mqtts://host:port of the broker the robot uses.")
@click.option(
    "--ros",
    type=click.Choice(["1", "2"]),
    default="2",
    show_default=True,
    help="ROS version the robot runs (as `run --ros`): its message layouts, e.g. time as secs/nsecs or sec/nanosec.",
)
@click.option(
    "--topic-root",
    default="td2adaptor",
    show_default=True,
    help="First level of every topic (as the run configuration's topic_root).",
)
@click.option(
    "--property-qos",
    type=click.Choice(["0", "1"]),
    default="1",
    show_default=True,
    help="MQTT QoS of property events (as the run configuration's property_qos), which the observe forms say.",
)
@click.option(
    "--basic",
    is_flag=True,
    help="The broker wants a user name and password (the node runs with TD2ADAPTOR_MQTT_USERNAME set): a TD that "
    "declares nosec is written with basic security, as `run` publishes it then.",
)
@click.option(
    "--output",
    "-o",
    default="-",
    show_default=True,
    help="Where to write the Thing Description ('-': stdout).",
)
def expose(
    source: str,
    interfaces: tuple[Path, ...],
    sets: tuple[str, ...],
    values_file: Path | None,
    strict: bool,
    no_cache: bool,
    max_bytes: int,
    max_affordances: int,
    robot: str,
    broker: str,
    ros: str,
    topic_root: str,
    property_qos: str,
    basic: bool,
    output: str,
) -> None:
    """Write the Thing Description of one robot as its edge node exposes it on the broker.

    The robot's affordances with W3C MQTT binding forms on the topics `td2adaptor run --robot ROBOT` serves
    (the topic in each href's path too), its id unique per robot; `run` publishes the same text, retained, on
    td2adaptor/<robot>/td while it runs. (`gen -b events` writes the fleet's Thing Model, td.mqtt.json.)
    """
    from td2adaptor.model.events import ALL_ROBOTS, ROBOT_ID, build_catalog
    from td2adaptor.model.exposed import exposed_td
    from td2adaptor.runtime.bus.security import SecurityError, parse_broker_url
    from td2adaptor.support.jsondump import dump

    if not ROBOT_ID.match(robot) or robot == ALL_ROBOTS:
        _fail("expose", f"robot id {robot!r} must be 1-128 letters, digits, '_', '.', '-' (and not {ALL_ROBOTS!r})")
    if not topic_root or any(c in topic_root for c in "+#\x00") or topic_root.startswith("/"):
        _fail("expose", f"topic root {topic_root!r} is not a valid MQTT topic prefix")
    try:
        url = parse_broker_url(broker).url
    except SecurityError as exc:
        _fail("expose", str(exc))
    result = _compile([source], interfaces, sets, values_file, strict, max_bytes, None, no_cache, max_affordances)
    if result.model is None:
        report(result.diagnostics, "human", label=_label([source]))
        sys.exit(EXIT_INVALID)
    catalog = build_catalog(result.model, f"ros{ros}")
    td = exposed_td(
        result.model,
        catalog,
        robot=robot,
        broker=url,
        root=topic_root,
        property_qos=int(property_qos),
        authenticated=basic,
    )
    text = dump(td)
    if output == "-":
        click.echo(text, nl=False)
    else:
        from td2adaptor.support.fsutil import write_atomic

        write_atomic(Path(output), text.encode("utf-8"))
    sys.exit(EXIT_OK)


@cli.group()
def demo() -> None:
    """Demonstrations that run on a simulated robot (from a source checkout)."""


@demo.command()
@click.option("--bus", default="local", show_default=True, help="local, or mqtt://host:port of a running broker.")
@click.option("--robots", type=click.IntRange(1, 3), default=3, show_default=True, help="How many robots.")
@click.option(
    "--robot-kind",
    type=click.Choice(["rb1", "nav_base"]),
    default="rb1",
    show_default=True,
    help="The example robot: RB-1 (procedures on services) or nav_base (Nav2-style ROS actions).",
)
@click.option(
    "--duration",
    type=float,
    default=1.0,
    show_default=True,
    callback=_positive,
    help="Seconds each simulated procedure takes (nav_base: a 3 m drive, a docking).",
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
    bus: str,
    robots: int,
    robot_kind: str,
    duration: float,
    timeout: float,
    cache_dir: Path | None,
    allow_insecure: bool,
    verbose: bool,
) -> None:
    """Three robots (RB-1s, or nav_base) move three carts through a door into storage zones A/B/C (ROS 2 Jazzy,
    simulated).

    A behaviour service that talks only events over the bus takes carts from a shared SQLite task table and
    drives the robots through their edge nodes; with --bus mqtt://... every edge node is its own process.
    Prints a summary (carts moved, bus messages per action, total time); exit 0 when every cart is stored.
    """
    demo_module = _checkout_module("examples.warehouse.warehouse")
    if demo_module is None:
        _fail(
            "demo warehouse",
            "the demo runs from a source checkout of td2adaptor (it needs examples/: the example robots, their "
            "simulations and the warehouse); this installation has none",
        )
    DemoError, WarehouseOptions, run_warehouse = (
        demo_module.DemoError,
        demo_module.WarehouseOptions,
        demo_module.run_warehouse,
    )
    options = WarehouseOptions(
        bus=bus,
        robots=robots,
        robot_kind=robot_kind,
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


def _summarise(diagnostics: Sequence[Diagnostic], source: str, given: Sequence[str] = ()) -> None:
    """The TD's problems at start-up: errors and the first warning in full, the rest (warnings, notes)
    counted by code; a node restarts often, and `validate` is where to read them all. `given`: the -I, --set
    and --values arguments run got, which the suggested validate command needs to find the same problems."""
    import shlex
    from collections import Counter

    errors = [d for d in diagnostics if d.severity.value == "error"]
    others = [d for d in diagnostics if d.severity.value != "error"]
    first = next((d for d in others if d.severity.value == "warning"), None)
    rest = [d for d in others if d is not first]
    if len(rest) <= 1:
        report(diagnostics, "human", label=_label([source]))
        return
    report([*errors, *([first] if first else [])], "human", label=_label([source]), counted=diagnostics)
    counts = Counter(d.code for d in rest)
    codes = ", ".join(f"{code} x{n}" for code, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))
    command = shlex.join(["td2adaptor", "validate", source, *given])
    shown = bool(errors) or first is not None  # nothing above the verdict: no "... and N more" of nothing
    lead = f"... and {len(rest)} more" if shown else f"{len(rest)} notes"
    click.echo(f"{lead} ({codes}); `{command}` lists them", err=True)
