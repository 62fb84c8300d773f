"""The edge process's metrics in the Prometheus text format (`run --metrics 127.0.0.1:PORT`), with the
`prometheus-client` library: its HTTP server on a thread of its own, and a collector that reads the robots this
process serves (status.py's keepers) at each scrape, so nothing is counted twice and a robot that leaves is
gone from the next scrape.

Every series has the label `robot`:

* `td2adaptor_robots_owned`: robots this process serves (no label);
* `td2adaptor_robot_online` 1 while served; `td2adaptor_robot_present` 1 / 0.5 / 0 for its ROS side present /
  partial / absent (no series before the first look, or without one: ROS 1);
* `td2adaptor_missions_in_flight`; `td2adaptor_missions_started_total` (every invoke run: procedures, ROS action
  goals and plain calls, as the durations count them); `td2adaptor_mission_duration_seconds` (histogram, label
  `state`: how each ended);
* `td2adaptor_events_in_total`, `td2adaptor_errors_total` (error events), `td2adaptor_refused_total`
  (commands not run: stale, replayed, retained, `absent`, ...);
* `td2adaptor_mqtt_reconnects_total`: reconnections of the robot's MQTT connection.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Iterator
from typing import Any

from prometheus_client import CollectorRegistry, start_http_server
from prometheus_client.core import CounterMetricFamily, GaugeMetricFamily, HistogramMetricFamily
from prometheus_client.registry import Collector

from td2adaptor.runtime.node.presence import PARTIAL, PRESENT
from td2adaptor.runtime.node.status import DURATION_BUCKETS, keepers


class MetricsError(ValueError):
    """A `--metrics` address that cannot be served; the message says why."""


def parse_address(text: str) -> tuple[str, int]:
    """`HOST:PORT` (an IP address; `[::1]:PORT` for IPv6) as (host, port); port 0 takes a free one, as
    `dashboard --listen` does (the start line then says which)."""
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit():
        raise MetricsError(f"metrics address {text!r}: give HOST:PORT, e.g. 127.0.0.1:9464")
    if not 0 <= int(port) < 65536:
        raise MetricsError(f"metrics address {text!r}: the port must be 0-65535 (0: a free one)")
    try:
        ipaddress.ip_address(host)
    except ValueError:
        raise MetricsError(f"metrics address {text!r}: the host must be an IP address, e.g. 127.0.0.1") from None
    return host, int(port)


def _bound(value: float) -> str:
    return "+Inf" if value == float("inf") else repr(value)


class EdgeCollector(Collector):
    """Reads the robots this process serves at each scrape (see the module docstring)."""

    def collect(self) -> Iterator[Any]:
        served = keepers()
        owned = GaugeMetricFamily("td2adaptor_robots_owned", "Robots this edge process serves.")
        owned.add_metric([], len(served))
        yield owned
        online = GaugeMetricFamily(
            "td2adaptor_robot_online", "1 while this process serves the robot.", labels=["robot"]
        )
        present = GaugeMetricFamily(
            "td2adaptor_robot_present",
            "The robot's ROS side: 1 present, 0.5 partial (some action servers missing), 0 absent.",
            labels=["robot"],
        )
        flight = GaugeMetricFamily("td2adaptor_missions_in_flight", "Missions in flight.", labels=["robot"])
        started = CounterMetricFamily("td2adaptor_missions_started", "Missions started.", labels=["robot"])
        events = CounterMetricFamily("td2adaptor_events_in", "Inbound events handled.", labels=["robot"])
        errors = CounterMetricFamily("td2adaptor_errors", "Error events published.", labels=["robot"])
        refused = CounterMetricFamily(
            "td2adaptor_refused", "Commands not run (stale, replayed, retained, robot absent, ...).", labels=["robot"]
        )
        reconnects = CounterMetricFamily(
            "td2adaptor_mqtt_reconnects", "Reconnections of the robot's MQTT connection.", labels=["robot"]
        )
        durations = HistogramMetricFamily(
            "td2adaptor_mission_duration_seconds",
            "How long missions took, from the invoke to the terminal event, by how they ended.",
            labels=["robot", "state"],
        )
        for keeper in served:
            engine = keeper.engine
            robot = engine.config.robot
            stats = dict(engine.stats)
            online.add_metric([robot], 1)
            word = keeper.presence.word()
            if word is not None:
                present.add_metric([robot], 1.0 if word == PRESENT else 0.5 if word == PARTIAL else 0.0)
            flight.add_metric([robot], len(engine.missions.running()))
            started.add_metric([robot], stats.get("missions", 0))
            events.add_metric([robot], stats.get("in", 0))
            errors.add_metric([robot], stats.get("out.error", 0))
            refused.add_metric([robot], stats.get("refused", 0) + stats.get("absent", 0))
            reconnects.add_metric([robot], max(0, int(getattr(keeper.raw, "connects", 1)) - 1))
            for state, (counts, total) in sorted(keeper.durations.snapshot().items()):
                cumulative, buckets = 0, []
                for bound, count in zip(DURATION_BUCKETS, counts, strict=True):
                    cumulative += count
                    buckets.append((_bound(bound), cumulative))
                durations.add_metric([robot, state], buckets, total)
        yield from (online, present, flight, started, events, errors, refused, reconnects, durations)


def served_address(server: Any) -> str:
    """The HOST:PORT `server` listens on (the port the system chose for port 0), as a URL writes it."""
    host, port = server.server_address[:2]
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def serve_metrics(address: str) -> Any:
    """Serve the metrics on `address` (HOST:PORT) over HTTP (`/metrics`, or any path) until the process ends;
    the server (its `shutdown()` stops it). Raises `MetricsError` when the address cannot be served."""
    host, port = parse_address(address)
    registry = CollectorRegistry(auto_describe=False)
    registry.register(EdgeCollector())
    try:
        server, _thread = start_http_server(port, addr=host, registry=registry)
    except OSError as exc:
        raise MetricsError(f"cannot serve metrics on {address}: {exc.strerror or exc}") from None
    return server
