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
import os
import signal
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from td2adaptor.model import Model
from td2adaptor.runtime.bus.localbus import LocalBroker
from td2adaptor.runtime.config import STAND_IN, RuntimeConfig
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.node.app import bus_security, td_broker
from td2adaptor.runtime.node.claims import check_fleet
from td2adaptor.runtime.node.fleet import Fleet
from td2adaptor.runtime.node.roslink import RosLink, connect

if TYPE_CHECKING:
    from td2adaptor.runtime.node.admin import Admin
    from td2adaptor.runtime.node.graphwatch import Discovery
    from td2adaptor.runtime.node.share import Share

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
        defaults: Mapping[str, Any] | None = None,
        metrics: str | None = None,
    ) -> None:
        self.model = model
        self.metrics = metrics  # HOST:PORT to serve the Prometheus metrics on (metrics.py), or None
        self._metrics_server: Any = None
        self.defaults = dict(defaults or {})  # the shared settings of robots that join later (config.load_defaults)
        self.configs = list(configs)
        self.options = options
        self.broker = broker
        self.package = options.package or model.package_name
        self.link: RosLink | None = None
        self.fleet: Fleet | None = None  # the robots served: the one place that changes them (node/fleet.py)
        self._stopped = threading.Event()
        self._extras: list[Callable[[], None]] = []  # discovery, admin requests: stopped first
        self.halted = threading.Event()  # set when a robot's bus stopped serving its broker (`failure` says why)
        self.failure: str | None = None
        self.shared: Share | None = None  # `run --share`: this process's part of a fleet shared with others

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
            from td2adaptor.runtime.node.metrics import serve_metrics, served_address

            self._metrics_server = serve_metrics(self.metrics)  # MetricsError: the address cannot be served
            self.metrics = served_address(self._metrics_server)  # port 0: the one the system chose
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
        self.fleet = Fleet(
            self.model, self.link, distro=f"ros{self.options.ros}", broker=self.broker, on_halt=self._halt
        )
        try:
            self.fleet.start(self.configs)
        except BaseException:
            self.link.close()
            raise

    def discover(self) -> Discovery:
        """Serve every robot of the model the ROS graph shows, as they come and go (node/graphwatch.py); in a
        shared fleet (`share` first) the share gives each one to a process that sees it. Raises `ConfigError`
        when the model names no interface under the robot's namespace."""
        from td2adaptor.runtime.config import robot_config
        from td2adaptor.runtime.node.graphwatch import Discovery, ros1_graph, ros2_graph, signature

        assert self.fleet is not None and self.link is not None
        sig = signature(self.model)
        template = robot_config(self.defaults, STAND_IN)
        if self.options.ros == 2:
            assert self.link.graph is not None
            graph = ros2_graph(self.link.graph, template.ros_domain_id, os.environ)
        else:
            graph = ros1_graph(template.ros_master_uri, os.environ)
        discovery = Discovery(
            self.shared or self.fleet,
            graph,
            sig,
            lambda robot, namespace: robot_config(self.defaults, robot, namespace),
            grace=template.discover_grace,
        )
        if self.shared is not None:
            self.shared.follow(discovery)  # it looks at once when another member finds a robot
        discovery.start()
        self._extras.append(discovery.stop)
        return discovery

    def share(self, candidates: Sequence[RuntimeConfig]) -> Share:
        """Serve this process's share of `candidates` with the other processes of the fleet on the broker
        (node/share.py); raises `SecurityError` or `BusError` as a robot's connection would."""
        from td2adaptor.runtime.config import robot_config
        from td2adaptor.runtime.node.share import Share, share_bus

        assert self.fleet is not None
        for config in candidates:
            td_broker(config)
            bus_security(config, self.model)
        template = robot_config(self.defaults, STAND_IN)
        name = template.fleet or self.model.package_name
        bus = share_bus(template, self.model, name=name, keepalive=template.share_keepalive)
        shared = self.shared = Share(
            self.fleet,
            bus,
            name=name,
            root=template.topic_root,
            timeout=template.share_timeout,
            make_config=lambda robot, namespace: robot_config(self.defaults, robot, namespace),
        )
        shared.start(candidates)
        self._extras.append(shared.stop)
        return shared

    def listen_admin(self) -> Admin:
        """Take admin requests on the bus (node/admin.py); in a shared fleet (`share` first) they change the
        shared fleet. Raises `SecurityError` or `BusError` as a robot's connection would."""
        from td2adaptor.runtime.config import robot_config
        from td2adaptor.runtime.node.admin import Admin, admin_bus

        assert self.fleet is not None
        template = robot_config(self.defaults, STAND_IN)
        admin = Admin(
            self.fleet,
            admin_bus(template, self.model, broker=self.broker),
            name=template.fleet or self.model.package_name,
            root=template.topic_root,
            key=template.fleet_admin_key,
            make_config=lambda robot, namespace: robot_config(self.defaults, robot, namespace),
            freshness_window=template.freshness_window,
            clock_skew=template.clock_skew,
            share=self.shared,
        )
        admin.start()
        self._extras.append(admin.stop)
        return admin

    @property
    def engines(self) -> list[Engine]:
        """The engines of the robots served now."""
        return [] if self.fleet is None else self.fleet.engines()

    def _halt(self, robot: str, reason: str) -> None:
        """A robot's bus stopped serving its broker (it failed the check every connection passes): the node
        does not go on half-served; `run` stops it and exits with `reason`. In a shared fleet a robot another
        member took over (its session taken) only leaves this process; the share gives out the robots again."""
        if self.shared is not None and "took its session over" in reason:
            return  # the share lets the robot go (share.py)
        if self.failure is None:
            self.failure = f"robot {robot}: {reason}"
        self.halted.set()

    def stop(self) -> None:
        """Stop serving (offline status published by each engine), then leave the ROS graph. Idempotent."""
        if self._stopped.is_set():
            return
        self._stopped.set()
        for stop in reversed(self._extras):  # no more changes of the fleet
            try:
                stop()
            except Exception:  # noqa: BLE001 - stopping: the robots still go offline
                log.exception("while stopping")
        if self.fleet is not None:
            self.fleet.stop()
        if self.link is not None:
            self.link.close()
        server, self._metrics_server = self._metrics_server, None
        if server is not None:
            server.shutdown()
            server.server_close()

    def describe(self) -> str:
        configs = list(self.fleet.robots().values()) if self.fleet is not None else self.configs
        robots = ", ".join(f"{c.robot} (namespace {c.ros_namespace or '/'})" for c in configs) or "no robot yet"
        if self.shared is not None:
            robots = f"its share of fleet {self.shared.name} (now {len(configs)} robots)"
        from td2adaptor.runtime.bus.security import redact_url

        bus = redact_url(self.defaults.get("bus", "local") if not self.configs else self.configs[0].bus)
        how = self.link.description if self.link is not None else f"ROS {self.options.ros}"
        directory = self.configs[0].directory if self.configs else self.defaults.get("directory")
        registered = f"; TDs registered with {redact_url(directory)}" if directory else ""
        metrics = f"; metrics on http://{self.metrics}/metrics" if self.metrics else ""
        return f"serving {robots} on {bus} via {how}{registered}{metrics}"


def wait_for_signal(
    stop: threading.Event | None = None,
    *,
    reload: Callable[[], object] | None = None,
    tick: Callable[[], object] | None = None,
    period: float = 0.5,
) -> int:
    """Block until SIGINT or SIGTERM (or `stop` is set); the signal number (0 for `stop`). SIGHUP calls
    `reload` (in this thread, not in the signal handler; without one it is logged and ignored instead of
    ending the process); `tick` is called every `period` seconds (a fleet file's look for changes)."""
    stop = stop or threading.Event()
    wake = threading.Event()
    got: list[int] = []
    hangups: list[int] = []

    def handler(signum: int, _frame: FrameType | None) -> None:
        got.append(signum)
        wake.set()

    def hangup(signum: int, _frame: FrameType | None) -> None:
        hangups.append(signum)
        wake.set()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    previous[signal.SIGHUP] = signal.signal(signal.SIGHUP, hangup)
    try:
        while not got and not stop.is_set():
            wake.wait(period)
            wake.clear()
            if got or stop.is_set():
                break
            if hangups:
                hangups.clear()
                if reload is None:
                    log.info("SIGHUP: no fleet file to reload")
                else:
                    _guarded(reload, "reloading the fleet file")
            elif tick is not None:
                _guarded(tick, "looking for changes of the fleet file")
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
    return got[0] if got else 0


def _guarded(call: Callable[[], object], what: str) -> None:
    """One call of the main loop: a failure is logged, and the node goes on serving."""
    try:
        call()
    except Exception:
        log.exception("%s failed", what)
