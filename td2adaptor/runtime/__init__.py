"""The event runtime: an edge node that turns bus events into robot calls and reports the outcome.

`RobotPort` (port.py) is the robot side, `Bus` (bus.py) the event side with a local and an MQTT
implementation, `Engine` (engine.py) the loop between them, `serve` (app.py) puts them together from a
`RuntimeConfig` (config.py). The event schemas come from `td2adaptor.backends.events_catalog`.
"""

from __future__ import annotations

from td2adaptor.runtime.app import open_bus, serve, serve_fleet
from td2adaptor.runtime.bus import Bus, BusError, Message
from td2adaptor.runtime.config import ConfigError, RuntimeConfig, load_config, load_fleet
from td2adaptor.runtime.engine import Engine
from td2adaptor.runtime.localbus import LocalBroker, LocalBus
from td2adaptor.runtime.port import (
    NoValue,
    PortCallFailed,
    PortError,
    PortTimeout,
    PortUnavailable,
    RobotPort,
    StartResult,
)
from td2adaptor.runtime.security import SecurityError

__all__ = [
    "Bus",
    "BusError",
    "ConfigError",
    "Engine",
    "LocalBroker",
    "LocalBus",
    "Message",
    "NoValue",
    "PortCallFailed",
    "PortError",
    "PortTimeout",
    "PortUnavailable",
    "RobotPort",
    "SecurityError",
    "StartResult",
    "RuntimeConfig",
    "load_config",
    "load_fleet",
    "open_bus",
    "serve",
    "serve_fleet",
]
