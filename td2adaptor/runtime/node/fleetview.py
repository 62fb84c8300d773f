"""The operator's view of a fleet (`td2adaptor fleet status`): every robot's retained status on a broker, read
once on a connection of its own, as rows of a table.

Nothing is asked of the edge nodes: what a robot's status says (status.py) is what the broker keeps, so the view
also shows robots whose node died (`offline`, through the will) and the process that served them last. Where
processes share a fleet (`run --share`, share.py) their member records are retained too: the view lists the
members, how many robots each serves, and the robots each took over from another process (a hand-over or the
takeover of a dead one's robots).
"""

from __future__ import annotations

import os
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


@dataclass(frozen=True)
class MemberRow:
    """One process of a shared fleet, as its retained member record says."""

    fleet: str
    owner: Owner | None
    joined: str
    robots: tuple[str, ...]
    takeovers: tuple[Mapping[str, Any], ...]

    def cells(self) -> list[str]:
        owner = f"{self.owner.pid}@{self.owner.host} since {self.owner.started}" if self.owner else "?"
        return [self.fleet, owner, self.joined, str(len(self.robots)), str(len(self.takeovers))]


def member_of(fleet: str, payload: bytes) -> MemberRow | None:
    try:
        record = orjson.loads(payload)
    except orjson.JSONDecodeError:
        return None
    if not isinstance(record, Mapping):
        return None
    robots = record.get("robots")
    takeovers = record.get("takeovers")
    return MemberRow(
        fleet,
        Owner.from_json(record.get("owner")),
        str(record.get("joined") or "?"),
        tuple(str(r) for r in robots) if isinstance(robots, list) else (),
        tuple(t for t in takeovers if isinstance(t, Mapping)) if isinstance(takeovers, list) else (),
    )


@dataclass(frozen=True)
class FleetView:
    robots: list[RobotRow]
    members: list[MemberRow]


def read_fleet(
    url: str,
    *,
    root: str = "td2adaptor",
    mqtt_version: str = "5",
    tls_ca_file: str | None = None,
    env: Mapping[str, str] | None = None,
    timeout: float = 5.0,
) -> list[RobotRow]:
    """Every robot's row (see `read_view`)."""
    return read_view(
        url, root=root, mqtt_version=mqtt_version, tls_ca_file=tls_ca_file, env=env, timeout=timeout
    ).robots


def read_view(
    url: str,
    *,
    root: str = "td2adaptor",
    mqtt_version: str = "5",
    tls_ca_file: str | None = None,
    env: Mapping[str, str] | None = None,
    timeout: float = 5.0,
) -> FleetView:
    """Every robot's row, by robot id, and every member of a shared fleet, from the retained statuses and member
    records under `root` on the broker at `url`; credentials from `TD2ADAPTOR_MQTT_USERNAME` /
    `TD2ADAPTOR_MQTT_PASSWORD` in `env`. Raises `SecurityError` for a URL
    that is no broker's, `BusError` when the broker cannot be reached or refuses (the message says which)."""
    from td2adaptor.runtime.bus.mqttbus import MqttBus

    env = os.environ if env is None else env
    address = parse_broker_url(url)
    tls = TlsOptions(tls_ca_file) if tls_ca_file else None
    security = ConnectionSecurity(env.get(ENV_USERNAME) or None, env.get(ENV_PASSWORD) or None, tls)
    bus = MqttBus.sessionless(address, security, "fleet", mqtt_version=mqtt_version, connect_timeout=timeout)
    bus.probe = True  # a refusal is this command's one line (`fleet status`), not also the connection's log lines
    got: dict[str, bytes] = {}
    members: dict[tuple[str, str], bytes] = {}
    lock = threading.Lock()

    def take(message: Message) -> None:
        parts = message.topic.split("/")
        if len(parts) >= 2 and message.payload:
            with lock:
                got[parts[-2]] = message.payload

    def member(message: Message) -> None:
        parts = message.topic.split("/")  # <root>/.fleet/<fleet>/members/<node>
        if message.payload:
            with lock:
                members[(parts[-3], parts[-1])] = message.payload

    bus.subscribe(f"{root}/+/status", take)
    bus.subscribe(f"{root}/.fleet/+/members/+", member)
    try:
        bus.connect()
        bus.subscribe(f"{root}/+/status/+", lambda _m: None)  # acknowledged after every retained status came
        with lock:
            seen, joined = dict(got), dict(members)
    finally:
        bus.close()
    rows = [row_of(robot, payload) for robot, payload in sorted(seen.items())]
    found = [member_of(fleet, payload) for (fleet, _node), payload in sorted(joined.items())]
    return FleetView(rows, sorted((m for m in found if m is not None), key=lambda m: (m.fleet, m.joined)))


HEADER = ["ROBOT", "STATE", "ROBOT SIDE", "OWNER", "MISSIONS", "LAST ERROR"]


MEMBER_HEADER = ["FLEET", "MEMBER PROCESS", "JOINED", "ROBOTS", "TAKEOVERS"]
TAKEOVER_HEADER = ["ROBOT", "TAKEN BY", "FROM", "HOW", "WHEN"]


def table(rows: Sequence[RobotRow]) -> str:
    """The rows as a plain-text table, columns aligned (the last one as long as it is)."""
    return _aligned([HEADER, *(r.cells() for r in rows)])


def members_table(members: Sequence[MemberRow]) -> str:
    """The members of shared fleets, then every takeover they remember (newest last)."""
    out = _aligned([MEMBER_HEADER, *(m.cells() for m in members)])
    took = []
    for m in members:
        by = f"{m.owner.pid}@{m.owner.host}" if m.owner else "?"
        for t in m.takeovers:
            was = Owner.from_json(t.get("from"))
            took.append(
                [
                    str(t.get("robot")),
                    by,
                    f"{was.pid}@{was.host}" if was else "?",
                    str(t.get("how")),
                    str(t.get("time")),
                ]
            )
    if took:
        out += "\n" + _aligned([TAKEOVER_HEADER, *sorted(took, key=lambda r: r[4])])
    return out


def _aligned(lines: Sequence[Sequence[str]]) -> str:
    widths = [max(len(line[i]) for line in lines) for i in range(len(lines[0]) - 1)]
    out = []
    for line in lines:
        out.append("  ".join([*(c.ljust(w) for c, w in zip(line, widths, strict=False)), line[-1]]).rstrip())
    return "\n".join(out) + "\n"


def members_json(members: Sequence[MemberRow]) -> list[dict[str, Any]]:
    return [
        {
            "fleet": m.fleet,
            "owner": m.owner.to_json() if m.owner else None,
            "joined": m.joined,
            "robots": list(m.robots),
            "takeovers": [dict(t) for t in m.takeovers],
        }
        for m in members
    ]


def as_json(rows: Sequence[RobotRow]) -> list[dict[str, Any]]:
    return [
        {
            "robot": r.robot,
            "state": r.state,
            "robotSide": None if r.presence == "-" else r.presence,  # offline, or not watched: null, as missions
            "missing": list(r.missing),
            "owner": r.owner.to_json() if r.owner else None,
            "missions": r.missions,
            "lastError": r.last_error or None,
        }
        for r in rows
    ]
