"""The dashboard's one MQTT connection, secured as the edge node's is (docs/security.md): the same broker URL
rules, credentials from `TD2ADAPTOR_MQTT_USERNAME` / `TD2ADAPTOR_MQTT_PASSWORD` (never on the command line, so
never in a process list), TLS files from `TD2ADAPTOR_TLS_*`, and no password sent in clear to another host."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.bus.security import TlsOptions, parse_broker_url, plan_security
from td2adaptor.runtime.config import ConfigError, from_env

__all__ = ["BusSettings", "ConfigError", "open_dashboard_bus"]


@dataclass(frozen=True)
class BusSettings:
    """What the command line says about the bus; the rest comes from the environment."""

    url: str
    allow_insecure: bool = False
    mqtt_version: str | None = None


def open_dashboard_bus(settings: BusSettings, env: Mapping[str, str] | None = None) -> MqttBus:
    """An unconnected `MqttBus` for the dashboard: a clean session of its own (a viewer needs no messages from
    while it was away: the retained ones tell the present), no will, no birth. Raises `SecurityError` (what to
    change) or `ConfigError` (a bad `TD2ADAPTOR_*` value)."""
    env = os.environ if env is None else env
    values = from_env(env)
    address = parse_broker_url(settings.url)
    files = (values.get("tls_ca_file"), values.get("tls_cert_file"), values.get("tls_key_file"))
    tls = TlsOptions(*files) if any(files) else None
    security = plan_security(
        None,
        address,
        username=values.get("username"),
        password=values.get("password"),
        tls=tls,
        allow_insecure=settings.allow_insecure or bool(values.get("allow_insecure")),
        env=env,
    )
    version = settings.mqtt_version or str(values.get("mqtt_version") or "5")
    return MqttBus.sessionless(
        address, security, "dashboard", mqtt_version=version, keepalive=int(values.get("keepalive") or 30)
    )
