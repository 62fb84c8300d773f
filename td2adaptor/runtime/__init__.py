"""The event runtime: an edge node that turns bus events into robot calls and reports the outcome.

`RobotPort` (port.py) is the robot side, `Bus` (bus.py) the event side with a local and an MQTT
implementation, `Engine` (engine.py) the loop between them, `serve` (app.py) puts them together from a
`RuntimeConfig` (config.py). The event schemas come from `td2adaptor.model.events`.
`genport.GeneratedPort` drives a robot through a generated rclpy/rospy package, `ros.py` connects it to a
ROS graph, `bridge.py` runs the ROS 1 side in ROS 1's own interpreter, `node.py` is `td2adaptor run`.

The names below load on first use: `td2adaptor.runtime.genport` and `td2adaptor.runtime.bridge` must stay
importable with the standard library alone (the ROS 1 bridge runs them under a ROS 1 interpreter that has
none of td2adaptor's dependencies).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from td2adaptor.runtime.app import open_bus, serve, serve_fleet
    from td2adaptor.runtime.bus import Bus, BusError, Message
    from td2adaptor.runtime.config import ConfigError, RuntimeConfig, load_config, load_fleet
    from td2adaptor.runtime.engine import Engine
    from td2adaptor.runtime.localbus import LocalBroker, LocalBus
    from td2adaptor.runtime.port import (
        GoalPort,
        GoalProgress,
        NoValue,
        PortCallFailed,
        PortError,
        PortRejected,
        PortTimeout,
        PortUnavailable,
        RobotPort,
        StartResult,
    )
    from td2adaptor.runtime.security import SecurityError

_WHERE = {
    "open_bus": "app",
    "serve": "app",
    "serve_fleet": "app",
    "Bus": "bus",
    "BusError": "bus",
    "Message": "bus",
    "ConfigError": "config",
    "RuntimeConfig": "config",
    "load_config": "config",
    "load_fleet": "config",
    "Engine": "engine",
    "LocalBroker": "localbus",
    "LocalBus": "localbus",
    "GoalPort": "port",
    "GoalProgress": "port",
    "NoValue": "port",
    "PortCallFailed": "port",
    "PortError": "port",
    "PortRejected": "port",
    "PortTimeout": "port",
    "PortUnavailable": "port",
    "RobotPort": "port",
    "StartResult": "port",
    "SecurityError": "security",
}

__all__ = [
    "Bus",
    "BusError",
    "ConfigError",
    "Engine",
    "GoalPort",
    "GoalProgress",
    "LocalBroker",
    "LocalBus",
    "Message",
    "NoValue",
    "PortCallFailed",
    "PortError",
    "PortRejected",
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


def __getattr__(name: str) -> Any:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module 'td2adaptor.runtime' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"td2adaptor.runtime.{module}"), name)
    globals()[name] = value
    return value
