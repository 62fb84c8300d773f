"""Who serves which robot of a shared fleet, and where its members meet on the broker: the pure part of
`run --share` (node/share.py), which every process computes alike from the same inputs.

* `assign`: rendezvous hashing with a bound on the load, so the shares differ by one robot at most and a member
  that leaves moves little but its own robots; `can` limits each robot to the members that list it.
* the topics under `<root>/.fleet/<fleet>/`: member records, beats, and the robots admin requests added;
* `read_status`: what a robot's retained status says about its owner (free, handed over, retired), and
  `orphaned`: whether it was handed over by a member that left; `names`: a member record's list of robots.
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import orjson

from td2adaptor.runtime.node.owner import Owner


def members_topic(root: str, fleet: str, node: str = "+") -> str:
    """Where a member's record is retained (`+`: every member's)."""
    return f"{root}/.fleet/{fleet}/members/{node}"


def beats_topic(root: str, fleet: str, node: str = "+") -> str:
    """Where a member beats (QoS 0, not retained)."""
    return f"{root}/.fleet/{fleet}/beats/{node}"


def entries_topic(root: str, fleet: str, robot: str = "+") -> str:
    """Where a robot added by an admin request is retained while it is in the fleet (admin.py, shared)."""
    return f"{root}/.fleet/{fleet}/robots/{robot}"


def _score(member: str, robot: str) -> int:
    return int.from_bytes(hashlib.sha256(f"{member}\x00{robot}".encode()).digest()[:8], "big")


def assign(
    robots: Iterable[str], members: Iterable[str], can: Mapping[str, Collection[str]] | None = None
) -> dict[str, str]:
    """Robot -> the member that serves it. Rendezvous hashing (each robot ranks the members by a hash of both)
    with a bound: every member gets floor(robots / members) robots, some one more, so the shares differ by one
    at most. The same inputs give the same answer in every process.

    `can` (member -> the robots it can serve: its fleet file's, the ones its discovery sees, the admin's) limits
    each robot to the members that list it; without it every member can serve every robot. A robot whose members
    are all at the bound goes to the least loaded of them; one no member lists is left out. The robots with the
    fewest members are given out first, so the bound leaves them a member."""
    ranked = sorted(set(members))
    wanted = sorted(set(robots))
    if not ranked:
        return {}

    def able(robot: str) -> list[str]:
        return ranked if can is None else [m for m in ranked if robot in can.get(m, ())]

    if can is not None:
        wanted.sort(key=lambda r: len(able(r)))  # stable: by name within the same count
    least, extra = divmod(len(wanted), len(ranked))  # `extra` members serve one robot more
    load = dict.fromkeys(ranked, 0)
    out: dict[str, str] = {}
    for robot in wanted:
        order = sorted(able(robot), key=lambda m: _score(m, robot), reverse=True)
        if not order:
            continue
        chosen = next((m for m in order if load[m] < least or (load[m] == least and extra > 0)), None)
        if chosen is None:  # every member that can serve it is full: the least loaded of them, by rank
            chosen = min(order, key=lambda m: load[m])
        elif load[chosen] == least:
            extra -= 1
        out[robot] = chosen
        load[chosen] += 1
    return out


@dataclass(frozen=True)
class Status:
    """What a robot's retained status says about its owner."""

    state: str
    owner: Owner | None
    handover: str | None  # the member it was handed over to, if it was
    retired: bool = False  # its owner stopped serving it because it no longer lists it (`Share._release`)


def read_status(payload: bytes) -> Status | None:
    try:
        event = orjson.loads(payload)
    except orjson.JSONDecodeError:
        return None
    body = event.get("payload") if isinstance(event, Mapping) else None
    if not isinstance(body, Mapping):
        return None
    state = body.get("state")
    handover = body.get("handover")
    to = handover.get("node") if isinstance(handover, Mapping) else None
    retired = isinstance(body.get("retired"), Mapping)
    return Status(state if isinstance(state, str) else "", Owner.from_json(body.get("owner")), to, retired)


def names(value: Any) -> set[str]:
    """A record's list of robot ids (nothing when it is not a list: a record of another version)."""
    return {v for v in value if isinstance(v, str)} if isinstance(value, list) else set()


def orphaned(status: Status, gone: set[str], live: set[str]) -> bool:
    """Whether the robot's status is "online, handed over" by a member of this fleet that left (`gone`), to one
    that did not take it."""
    owner = status.owner
    return (
        status.state == "online"
        and status.handover is not None
        and owner is not None
        and owner.node in gone
        and owner.node not in live
    )
