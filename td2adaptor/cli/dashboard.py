"""`td2adaptor dashboard`: the operator's web page of the fleet on a bus (td2adaptor/dashboard/)."""

from __future__ import annotations

import sys

import click

from td2adaptor.cli.common import EXIT_OK, _fail, cli


@cli.command()
@click.option("--bus", required=True, help="mqtt://host:port or mqtts://host:port of the fleet's broker.")
@click.option(
    "--listen",
    default="127.0.0.1:8080",
    show_default=True,
    help="HOST:PORT the page is served on (port 0: a free one); a non-loopback address needs --allow-remote.",
)
@click.option("--read-only", is_flag=True, help="Show the fleet; refuse every property write and action (server side).")
@click.option(
    "--allow-remote",
    is_flag=True,
    help="Allow a --listen address other than loopback (the page has no login: put it behind an authenticating proxy).",
)
@click.option("--topic-root", default="td2adaptor", show_default=True, help="First level of the robots' topics.")
@click.option(
    "--directory",
    help="W3C WoT Thing Description Directory (http(s)://host:port[/path]) to list robots from as well as the bus "
    "(token: TD2ADAPTOR_DIRECTORY_TOKEN).",
)
@click.option(
    "--directory-period",
    type=click.FloatRange(min=0.1),
    default=10.0,
    show_default=True,
    help="Seconds between two readings of the directory's listing.",
)
@click.option(
    "--mqtt-version", type=click.Choice(["5", "3.1.1"]), help="MQTT protocol version (default: 5, or the environment)."
)
@click.option("--allow-insecure", is_flag=True, help="Allow a plain connection to a broker not on this machine.")
def dashboard(
    bus: str,
    listen: str,
    read_only: bool,
    allow_remote: bool,
    topic_root: str,
    directory: str | None,
    directory_period: float,
    mqtt_version: str | None,
    allow_insecure: bool,
) -> None:
    """Serve a live web page of the robots on a bus, built from their own Thing Descriptions.

    Robots appear with their retained TD (td2adaptor/<robot>/td) and show their status, last error, every
    property live, a form for every action generated from its input schema, each mission's timeline, and a map
    when a property holds a pose. The server holds the one MQTT connection: credentials come from
    TD2ADAPTOR_MQTT_USERNAME / TD2ADAPTOR_MQTT_PASSWORD (TLS: TD2ADAPTOR_TLS_*) and never reach the page.
    """
    from td2adaptor.dashboard.connection import BusSettings, ConfigError
    from td2adaptor.dashboard.server import DashboardError, DashboardOptions, parse_listen, serve_dashboard
    from td2adaptor.runtime.bus.bus import BusError
    from td2adaptor.runtime.bus.security import SecurityError

    if not topic_root or any(c in topic_root for c in "+#\x00") or topic_root.startswith("/"):
        _fail("dashboard", f"topic root {topic_root!r} is not a valid MQTT topic prefix")
    try:
        options = DashboardOptions(
            BusSettings(bus, allow_insecure, mqtt_version),
            parse_listen(listen),
            read_only=read_only,
            allow_remote=allow_remote,
            topic_root=topic_root,
            directory=directory,
            directory_period=directory_period,
        )
        serve_dashboard(options, lambda line: click.echo(f"td2adaptor dashboard: {line}", err=True))
    except (DashboardError, SecurityError, ConfigError, BusError) as exc:
        _fail("dashboard", str(exc))
    except KeyboardInterrupt:
        pass
    click.echo("td2adaptor dashboard: stopped", err=True)
    sys.exit(EXIT_OK)
