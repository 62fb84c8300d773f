"""Exactly one edge-node process per robot: who owns a robot, and the check a process makes before it serves one.

Every robot's retained status (`<root>/<robot>/status`) names its `owner`, the process that serves it: host,
process id, the process's start time and a random id new at every start. The record is the status itself, so
the broker keeps it as it keeps the status: `online` while the process serves the robot, `offline` after a
clean stop, and `offline` through the MQTT will when the process dies, as soon as the broker notices (at once
when the connection closes, else after 1.5 x keepalive).

Before a process connects with a robot's session (its client id), `claim` reads the robot's retained status
on a connection of its own: a robot that another live process serves is refused (`OwnerConflict`), instead of
the two taking the one MQTT session from each other for ever. A record of this host whose process is gone
(killed before the broker noticed) is stale and does not count. Two processes started at the very same moment
both find the robot free: the broker then gives the session to the later one and tells the earlier one with
MQTT 5's "Session taken over", which stops it (mqttbus.py). A later failover step can build on the same
record: a process that takes a robot over knows whose it was.
"""

from __future__ import annotations

import os
import secrets
import socket
import threading
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

import orjson

from td2adaptor.runtime.bus.bus import BusError, Message

#: MQTT 5's DISCONNECT reason code: another connection with the same client id took the session over
SESSION_TAKEN_OVER = 142


class OwnerConflict(BusError):
    """Another live process serves the robot; the message says which and what to do."""


@dataclass(frozen=True)
class Owner:
    """The process that serves a robot, as its status names it."""

    host: str
    pid: int
    started: str  # RFC 3339, to the second: the same whoever reads it from /proc
    node: str  # random, new at every start: tells two runs of one pid apart

    def to_json(self) -> dict[str, Any]:
        return {"host": self.host, "pid": self.pid, "started": self.started, "node": self.node}

    @classmethod
    def from_json(cls, data: Any) -> Owner | None:
        if not isinstance(data, Mapping):
            return None
        host, pid, started, node = (data.get(k) for k in ("host", "pid", "started", "node"))
        if isinstance(host, str) and isinstance(pid, int) and isinstance(started, str) and isinstance(node, str):
            return cls(host, pid, started, node)
        return None

    def describe(self) -> str:
        return f"process {self.pid} on {self.host} (started {self.started})"


def process_started(pid: int) -> str | None:
    """When process `pid` started (RFC 3339, UTC, to the second), from /proc; None when it does not run (or
    there is no /proc to tell)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
        with open("/proc/stat", "rb") as f:
            boot = next(int(line.split()[1]) for line in f if line.startswith(b"btime "))
    except (OSError, StopIteration, ValueError):
        return None
    ticks = int(stat.rsplit(b")", 1)[1].split()[19])  # field 22, after the command name (which may hold blanks)
    started = boot + ticks // os.sysconf("SC_CLK_TCK")
    return datetime.fromtimestamp(started, timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


_me: Owner | None = None
_me_lock = threading.Lock()


def this_process() -> Owner:
    """This process as a robot's owner (the same record for every robot it serves)."""
    global _me
    with _me_lock:
        if _me is None or _me.pid != os.getpid():  # (a forked child is another process)
            started = process_started(os.getpid())
            if started is None:
                started = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
            _me = Owner(socket.gethostname(), os.getpid(), started, secrets.token_hex(8))
        return _me


def lives(owner: Owner) -> bool:
    """Whether `owner` may still serve: a process of another host is taken as alive (only the broker can tell,
    by its will); one of this host must run, and be the same process (not a later one with its pid)."""
    if owner.host != socket.gethostname():
        return True
    if owner.pid == os.getpid():
        return owner.node == this_process().node
    started = process_started(owner.pid)
    if started is not None:
        return started == owner.started
    try:
        os.kill(owner.pid, 0)  # no /proc: is there a process of that id at all?
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: it exists
        return True
    return True


def status_owner(payload: bytes) -> tuple[str, Owner | None]:
    """The state (`online`, `offline`, or "" when unreadable) and owner of a retained status message."""
    try:
        event = orjson.loads(payload)
    except orjson.JSONDecodeError:
        return "", None
    body = event.get("payload") if isinstance(event, Mapping) else None
    if not isinstance(body, Mapping):
        return "", None
    state = body.get("state")
    return (state if isinstance(state, str) else ""), Owner.from_json(body.get("owner"))


def conflict(robot: str, message: Message | None) -> str | None:
    """Why this process must not serve `robot`, given its retained status (None: it may)."""
    if message is None or not message.payload:
        return None
    state, owner = status_owner(message.payload)
    if state != "online" or owner is None or not lives(owner):
        return None
    return (
        f"robot {robot} is already served by {owner.describe()}: a second edge node for the same robot id would "
        "take its MQTT session and the two would push each other off the broker. Stop that process first (or "
        "give this robot another id); if it died without stopping, the broker clears its claim within 1.5 x its "
        "keepalive (its last will), and this process can be started then"
    )


def read_statuses(bus: Any, topics: Sequence[str]) -> dict[str, Message]:
    """The retained messages of `topics` (robots' statuses), read on `bus`: an unconnected bus of this process's
    own, not a robot's session; closed here. A broker sends a subscription's retained messages before it answers
    a later subscription on the same connection, so once a second subscription is acknowledged every retained
    status has come (`MqttBus.subscribe` returns after the acknowledgement; a filter the broker's ACL refuses is
    acknowledged all the same)."""
    got: dict[str, Message] = {}
    lock = threading.Lock()

    def take(message: Message) -> None:
        with lock:
            got[message.topic] = message

    for topic in topics:
        bus.subscribe(topic, take)
    try:
        bus.connect()  # returns once the subscriptions are acknowledged
        bus.subscribe(f"{topics[0]}/+", lambda _m: None)  # its acknowledgement: the retained ones are in
        with lock:
            return dict(got)
    finally:
        bus.close()


def claim(robots: Sequence[str], status_topics: Sequence[str], bus: Any) -> None:
    """Refuse (`OwnerConflict`) when another live process serves one of `robots`, from their retained statuses
    read on `bus` (see `read_statuses`)."""
    seen = read_statuses(bus, status_topics)
    problems = [
        why for robot, topic in zip(robots, status_topics, strict=True) if (why := conflict(robot, seen.get(topic)))
    ]
    if problems:
        raise OwnerConflict("; ".join(problems))


def probe_bus(address: Any, security: Any, mqtt_version: str, keepalive: int = 30) -> Any:
    """A connection of this process's own to read retained statuses: a fresh client id, no session."""
    from td2adaptor.runtime.bus.mqttbus import MqttBus

    return MqttBus.sessionless(address, security, "claim", mqtt_version=mqtt_version, keepalive=keepalive)


def taken_by(robot: str, message: Message | None, ours: Collection[bytes]) -> str | None:
    """On reconnecting: what took the robot's session over while this node was away (its retained status says
    `online` and is none of the statuses this node published, `ours`), or None."""
    if message is None or not message.payload or message.payload in ours:
        return None
    state, owner = status_owner(message.payload)
    if state != "online":
        return None
    who = owner.describe() if owner is not None else "another edge node"
    return f"took its session over: robot {robot} is served by {who} now"
