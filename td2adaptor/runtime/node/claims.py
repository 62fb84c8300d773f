"""The check before a process serves robots: does another live process serve one of them? (owner.py says how
it is told; this module reads the robots' statuses on their brokers, one connection per broker.)"""

from __future__ import annotations

from collections.abc import Sequence

from td2adaptor.model import Model
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.node.app import bus_security
from td2adaptor.runtime.node.owner import claim, probe_bus


def check_fleet(model: Model, configs: Sequence[RuntimeConfig]) -> None:
    """`claim` the robots of `configs` on their MQTT brokers (a local bus is this process's own: nothing to
    check). Raises `OwnerConflict`, or `BusError` / `SecurityError` when a broker cannot be reached or refuses
    the credentials."""
    groups: dict[tuple[str, str | None], list[RuntimeConfig]] = {}
    for config in configs:
        if config.bus != "local":
            groups.setdefault((config.bus, config.username), []).append(config)
    for members in groups.values():
        first = members[0]
        address, security = bus_security(first, model)
        bus = probe_bus(address, security, first.mqtt_version, first.keepalive)
        claim([c.robot for c in members], [f"{c.topic_root}/{c.robot}/status" for c in members], bus)
