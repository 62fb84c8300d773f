"""The event runtime: an edge node that turns bus events into robot calls and reports the outcome.

Four subpackages, in layers (docs/architecture.md; tests/runtime/test_layers.py keeps them):
`ros/` is the robot side (`RobotPort` in ros/port.py; `genport.GeneratedPort` drives a generated rclpy/rospy
package, `bridge.py` runs the ROS 1 side in ROS 1's own interpreter), `bus/` the event side (`Bus` in
bus/bus.py, a local and an MQTT implementation, the WoT topic adapter), `engine/` the loop between them
(`Engine` in engine/engine.py) and `node/` puts them together: `serve` (node/app.py) from a `RuntimeConfig`
(config.py), `roslink.py` connects ports to a ROS graph, `node.py` is `td2adaptor run`. The event schemas come
from `td2adaptor.model.events`.

The names below load on first use: `td2adaptor.runtime.ros.genport` and `td2adaptor.runtime.ros.bridge` (and
the packages above them) must stay importable with the standard library alone (the ROS 1 bridge runs them
under a ROS 1 interpreter that has none of td2adaptor's dependencies).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from td2adaptor.runtime.bus.bus import Bus, BusError, Message
    from td2adaptor.runtime.bus.localbus import LocalBroker, LocalBus
    from td2adaptor.runtime.bus.security import SecurityError
    from td2adaptor.runtime.config import ConfigError, RuntimeConfig, load_config, load_fleet
    from td2adaptor.runtime.engine.engine import Engine
    from td2adaptor.runtime.node.app import open_bus, serve, serve_fleet
    from td2adaptor.runtime.ros.port import (
        GoalEnd,
        GoalListener,
        GoalPort,
        NoValue,
        PortCallFailed,
        PortError,
        PortRejected,
        PortTimeout,
        PortUnavailable,
        RobotPort,
        StartResult,
    )

_WHERE = {
    "open_bus": "node.app",
    "serve": "node.app",
    "serve_fleet": "node.app",
    "Bus": "bus.bus",
    "BusError": "bus.bus",
    "Message": "bus.bus",
    "ConfigError": "config",
    "RuntimeConfig": "config",
    "load_config": "config",
    "load_fleet": "config",
    "Engine": "engine.engine",
    "LocalBroker": "bus.localbus",
    "LocalBus": "bus.localbus",
    "GoalPort": "ros.port",
    "GoalEnd": "ros.port",
    "GoalListener": "ros.port",
    "NoValue": "ros.port",
    "PortCallFailed": "ros.port",
    "PortError": "ros.port",
    "PortRejected": "ros.port",
    "PortTimeout": "ros.port",
    "PortUnavailable": "ros.port",
    "RobotPort": "ros.port",
    "StartResult": "ros.port",
    "SecurityError": "bus.security",
}

__all__ = [
    "Bus",
    "BusError",
    "ConfigError",
    "Engine",
    "GoalPort",
    "GoalEnd",
    "GoalListener",
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
