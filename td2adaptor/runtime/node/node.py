"""`td2adaptor run`: one edge node process serving one robot, or a whole fleet, on ROS and an event bus.

The command line compiles the TD and loads the configuration; `EdgeNode` connects the generated package
to ROS (`ros.connect`), serves every robot (`app.serve_fleet`: each robot's Thing Description retained on
`td2adaptor/<robot>/td`, then its `online` status) and, on `stop()`, stops the engines (each clears its TD,
publishes its retained `offline` status and flushes the bus) before it leaves the ROS graph. The MQTT will
publishes the same `offline` status when the process dies without stopping. When a robot's connection fails
the check every connection passes (a broker that lets anonymous clients in, docs/security.md), the node sets
`halted` with the reason in `failure`: `run` stops it and exits with that message.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from types import FrameType
from typing import Any

from td2adaptor.model import Model
from td2adaptor.runtime.bus.localbus import LocalBroker
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.node.app import bus_security, serve_fleet, td_broker
from td2adaptor.runtime.node.roslink import RosLink, connect
from td2adaptor.runtime.ros.port import RobotPort

log = logging.getLogger("td2adaptor.runtime")


@dataclass(frozen=True)
class RosOptions:
    """How to reach ROS: version, the generated package and where it (and its interfaces) can be found."""

    ros: int = 2
    package: str | None = None  # default: the model's package name
    package_paths: tuple[Path, ...] = ()
    prefixes: tuple[Path, ...] = ()
    ros1_python: str | None = None
    node_name: str | None = None


class EdgeNode:
    """The robots of `configs` on ROS (through the generated package) and on their bus; `stop()` ends it."""

    def __init__(
        self,
        model: Model,
        configs: Sequence[RuntimeConfig],
        options: RosOptions,
        *,
        broker: LocalBroker | None = None,
        metrics: str | None = None,
    ) -> None:
        self.model = model
        self.metrics = metrics  # HOST:PORT to serve the Prometheus metrics on (metrics.py), or None
        self._metrics_server: Any = None
        self.configs = list(configs)
        self.options = options
        self.broker = broker
        self.package = options.package or model.package_name
        self.link: RosLink | None = None
        self.engines: list[Engine] = []
        self._stopped = threading.Event()
        self.halted = threading.Event()  # set when a robot's bus stopped serving its broker (`failure` says why)
        self.failure: str | None = None

    def check_bus(self) -> None:
        """Refuse a bus the TD's security does not allow before anything connects (raises `SecurityError`)."""
        for config in self.configs:
            td_broker(config)  # the broker its TD names: a URL of a broker, without credentials
            if config.bus != "local":
                bus_security(config, self.model)

    def start(self) -> None:
        """Check the bus settings, connect to ROS, then to the bus; a failure closes what was opened."""
        self.check_bus()
        check_fleet(self.model, self.configs)  # no robot another live process serves (OwnerConflict)
        if self.metrics is not None:
            from td2adaptor.runtime.node.metrics import serve_metrics

            self._metrics_server = serve_metrics(self.metrics)  # MetricsError: the address cannot be served
        o = self.options
        self.link = connect(
            self.model,
            self.package,
            self.configs,
            ros=o.ros,
            package_paths=o.package_paths,
            prefixes=o.prefixes,
            ros1_python=o.ros1_python,
            name=o.node_name,
        )
        ports = self.link.ports

        def port_of(config: RuntimeConfig) -> RobotPort:
            return ports[config.robot]

        try:
            self.engines = serve_fleet(
                self.model, port_of, self.configs, broker=self.broker, distro=f"ros{self.options.ros}"
            )
        except BaseException:
            self.link.close()
            raise
        for engine in self.engines:
            engine.on_halt.append(partial(self._halt, engine.config.robot))
            if engine.failure is not None:  # halted before the hook was in place
                self._halt(engine.config.robot, engine.failure)

    def _halt(self, robot: str, reason: str) -> None:
        """A robot's bus stopped serving its broker (it failed the check every connection passes): the node
        does not go on half-served; `run` stops it and exits with `reason`."""
        if self.failure is None:
            self.failure = f"robot {robot}: {reason}"
        self.halted.set()

    def stop(self) -> None:
        """Stop serving (offline status published by each engine), then leave the ROS graph. Idempotent."""
        if self._stopped.is_set():
            return
        self._stopped.set()
        for engine in self.engines:
            engine.stop()
        if self.link is not None:
            self.link.close()
        server, self._metrics_server = self._metrics_server, None
        if server is not None:
            server.shutdown()
            server.server_close()

    def describe(self) -> str:
        robots = ", ".join(f"{c.robot} (namespace {c.ros_namespace or '/'})" for c in self.configs)
        from td2adaptor.runtime.bus.security import redact_url

        bus = redact_url(self.configs[0].bus)
        how = self.link.description if self.link is not None else f"ROS {self.options.ros}"
        directory = self.configs[0].directory
        registered = f"; TDs registered with {redact_url(directory)}" if directory else ""
        metrics = f"; metrics on http://{self.metrics}/metrics" if self.metrics else ""
        return f"serving {robots} on {bus} via {how}{registered}{metrics}"


def check_fleet(model: Model, configs: Sequence[RuntimeConfig]) -> None:
    """`claim` the robots of `configs` (`RuntimeConfig`s) on their MQTT brokers, one connection per broker (a
    local bus is this process's own: nothing to check). Raises `OwnerConflict`, or `BusError` / `SecurityError`
    when a broker cannot be reached or refuses the credentials."""
    from td2adaptor.runtime.node.owner import claim, probe_bus

    groups: dict[tuple[str, str | None], list[RuntimeConfig]] = {}
    for config in configs:
        if config.bus != "local":
            groups.setdefault((config.bus, config.username), []).append(config)
    for members in groups.values():
        first = members[0]
        address, security = bus_security(first, model)
        bus = probe_bus(address, security, first.mqtt_version, first.keepalive)
        claim([c.robot for c in members], [f"{c.topic_root}/{c.robot}/status" for c in members], bus)


def wait_for_signal(stop: threading.Event | None = None) -> int:
    """Block until SIGINT or SIGTERM (or `stop` is set); the signal number (0 for `stop`)."""
    stop = stop or threading.Event()
    got: list[int] = []

    def handler(signum: int, _frame: FrameType | None) -> None:
        got.append(signum)
        stop.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        while not stop.wait(0.5):
            pass
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
    return got[0] if got else 0
