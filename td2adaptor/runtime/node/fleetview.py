"""The operator's view of a fleet (`td2adaptor fleet status`): every robot's retained status on a broker, read
once on a connection of its own, as rows of a table.

Nothing is asked of the edge nodes: what a robot's status says (status.py) is what the broker keeps, so the view
also shows robots whose node died (`offline`, through the will) and the process that served them last.
"""

from __future__ import annotations

import os
import secrets
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import orjson

from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.security import ENV_PASSWORD, ENV_USERNAME, ConnectionSecurity, TlsOptions, parse_broker_url
from td2adaptor.runtime.node.owner import Owner


@dataclass(frozen=True)
class RobotRow:
    """One robot as its retained status says."""

    robot: str
    state: str  # online / offline / "?" (a status this version cannot read)
    presence: str  # present / partial / absent / "-" (offline, or not watched)
    owner: Owner | None
    missions: int | None
    last_error: str  # "code: message" or ""
    missing: tuple[str, ...] = ()

    def cells(self) -> list[str]:
        owner = f"{self.owner.pid}@{self.owner.host} since {self.owner.started}" if self.owner else "-"
        missions = "-" if self.missions is None or self.state != "online" else str(self.missions)
        presence = self.presence + (f" (missing {', '.join(self.missing)})" if self.missing else "")
        return [self.robot, self.state, presence, owner, missions, self.last_error or "-"]


def row_of(robot: str, payload: bytes) -> RobotRow:
    """A robot's row from its retained status message."""
    try:
        event = orjson.loads(payload)
    except orjson.JSONDecodeError:
        event = None
    body = event.get("payload") if isinstance(event, Mapping) else None
    if not isinstance(body, Mapping):
        return RobotRow(robot, "?", "-", None, None, "")
    state = str(body.get("state") or "?")
    presence = str(body.get("robot") or "-") if state == "online" else "-"
    missions = body.get("missions")
    error = body.get("lastError")
    last = ""
    if isinstance(error, Mapping):
        last = f"{error.get('code')}: {error.get('message')} ({error.get('time')})"
    missing = body.get("missing")
    return RobotRow(
        robot,
        state,
        presence,
        Owner.from_json(body.get("owner")),
        missions if isinstance(missions, int) and not isinstance(missions, bool) else None,
        last,
        tuple(str(m) for m in missing) if isinstance(missing, list) and state == "online" else (),
    )


def read_fleet(
    url: str,
    *,
    root: str = "td2adaptor",
    mqtt_version: str = "5",
    tls_ca_file: str | None = None,
    env: Mapping[str, str] | None = None,
    timeout: float = 5.0,
) -> list[RobotRow]:
    """Every robot's row, by robot id, from the retained statuses under `root` on the broker at `url`; credentials
    from `TD2ADAPTOR_MQTT_USERNAME` / `TD2ADAPTOR_MQTT_PASSWORD` in `env`. Raises `SecurityError` for a URL
    that is no broker's, `BusError` when the broker cannot be reached or refuses (the message says which)."""
    from td2adaptor.runtime.bus.mqttbus import MqttBus

    env = os.environ if env is None else env
    address = parse_broker_url(url)
    tls = TlsOptions(tls_ca_file) if tls_ca_file else None
    security = ConnectionSecurity(env.get(ENV_USERNAME) or None, env.get(ENV_PASSWORD) or None, tls)
    bus = MqttBus(
        address,
        security,
        client_id=f"td2adaptor-fleet-{secrets.token_hex(6)}",
        clean_start=True,
        session_expiry=0,
        mqtt_version=mqtt_version,
        connect_timeout=timeout,
    )
    got: dict[str, bytes] = {}
    lock = threading.Lock()

    def take(message: Message) -> None:
        parts = message.topic.split("/")
        if len(parts) >= 2 and message.payload:
            with lock:
                got[parts[-2]] = message.payload

    bus.subscribe(f"{root}/+/status", take)
    try:
        bus.connect()
        bus.subscribe(f"{root}/+/status/+", lambda _m: None)  # acknowledged after every retained status came
        with lock:
            seen = dict(got)
    finally:
        bus.close()
    return [row_of(robot, payload) for robot, payload in sorted(seen.items())]


HEADER = ["ROBOT", "STATE", "ROBOT SIDE", "OWNER", "MISSIONS", "LAST ERROR"]


def table(rows: Sequence[RobotRow]) -> str:
    """The rows as a plain-text table, columns aligned (the last one as long as it is)."""
    lines = [HEADER, *(r.cells() for r in rows)]
    widths = [max(len(line[i]) for line in lines) for i in range(len(HEADER) - 1)]
    out = []
    for line in lines:
        out.append("  ".join([*(c.ljust(w) for c, w in zip(line, widths, strict=False)), line[-1]]).rstrip())
    return "\n".join(out) + "\n"


def as_json(rows: Sequence[RobotRow]) -> list[dict[str, Any]]:
    return [
        {
            "robot": r.robot,
            "state": r.state,
            "robotSide": r.presence,
            "missing": list(r.missing),
            "owner": r.owner.to_json() if r.owner else None,
            "missions": r.missions,
            "lastError": r.last_error or None,
        }
        for r in rows
    ]
