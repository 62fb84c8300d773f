"""`td2adaptor fleet ...`: the operator's view of the robots on a broker (runtime/node/fleetview.py)."""

from __future__ import annotations

import sys

import click

from td2adaptor.cli.common import EXIT_OK, _fail, cli


@cli.group()
def fleet() -> None:
    """The robots the edge nodes serve on a broker, as their retained statuses say."""


@fleet.command()
@click.option("--bus", required=True, help="mqtt://host:port or mqtts://host:port of the broker.")
@click.option("--topic-root", default="td2adaptor", show_default=True, help="First level of every topic.")
@click.option("--mqtt-version", type=click.Choice(["5", "3.1.1"]), default="5", show_default=True)
@click.option("--tls-ca-file", help="CA certificate to trust an mqtts:// broker by (default: the system's).")
@click.option("--timeout", type=float, default=5.0, show_default=True, help="Seconds to wait for the broker.")
@click.option("--json", "as_json", is_flag=True, help="One JSON array of the robots instead of the tables.")
@click.option("--members", "members_json", is_flag=True, help="With --json: the members of shared fleets instead.")
def status(
    bus: str,
    topic_root: str,
    mqtt_version: str,
    tls_ca_file: str | None,
    timeout: float,
    as_json: bool,
    members_json: bool,
) -> None:
    """List every robot: its edge node online or offline, its ROS side (present, partial, absent), the process
    that serves it (or served it last), its missions in flight and its last error. Where processes share a fleet
    (run --share): its members, the robots each serves, and the robots each took over from another process.

    Read from the retained status topics (td2adaptor/<robot>/status); the broker user and password, if it wants
    them, come from TD2ADAPTOR_MQTT_USERNAME and TD2ADAPTOR_MQTT_PASSWORD (never from the command line)."""
    if members_json and not as_json:  # it used to be ignored: the user got the robots' table and no word why
        raise click.UsageError("--members goes with --json (without it the members are shown below the robots)")
    from td2adaptor.runtime.bus.bus import BusError
    from td2adaptor.runtime.bus.security import SecurityError
    from td2adaptor.runtime.node import fleetview

    try:
        view = fleetview.read_view(
            bus, root=topic_root, mqtt_version=mqtt_version, tls_ca_file=tls_ca_file, timeout=timeout
        )
    except (BusError, SecurityError) as exc:
        _fail("fleet status", str(exc))
    rows = view.robots
    if as_json:
        from td2adaptor.support.jsondump import dump

        data = fleetview.members_json(view.members) if members_json else fleetview.as_json(rows)
        click.echo(dump(data), nl=False)
    elif not rows:
        click.echo(f"no robot has a status under {topic_root}/ on this broker")
    else:
        click.echo(fleetview.table(rows), nl=False)
    if view.members and not as_json:
        click.echo("")
        click.echo(fleetview.members_table(view.members), nl=False)
    sys.exit(EXIT_OK)
