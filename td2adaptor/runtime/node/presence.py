"""Is the robot's ROS side there? What the edge node sees of the servers of a robot's actions.

A robot's edge node can be up while the robot is not (its ROS nodes stopped, crashed, or not started yet): the
robot's status then says `online` and `robot: absent`, and an invoke is answered at once (engine.py, error
`absent`) instead of after `call_timeout`. A `Probe` looks at the servers the way the port reaches them, cheaply
(no call is made):

* ROS 2 (a `GeneratedPort` on rclpy): each service client's `service_is_ready()` and each action client's
  `server_is_ready()`, which read the node's graph cache (DDS discovery): a server that stops cleanly is gone at
  once, one killed (SIGKILL, power) when DDS drops its participant (its lease: Fast DDS's default is 20 s);
* the simulated robot (`SimPort`): its `down` switch, when the test sets `watched`;
* anything else (the ROS 1 bridge, rospy): no probe; the status has no `robot` member and nothing is refused.

`Presence` keeps what the last look saw. An action whose server has never been seen is refused only once the
node has run longer than `grace` (its calls' own wait for a server): at start-up, discovery takes a moment,
and an invoke then waits for the server as it always did.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from td2adaptor.model.events import PRESENCE_WORDS, EventSpec

#: what a look at the robot's ROS side says: each action (TD affordance) and whether its server is there
Probe = Callable[[], Mapping[str, bool]]
PRESENT, PARTIAL, ABSENT = PRESENCE_WORDS


def ros2_probe(port: Any, actions: Iterable[str]) -> Probe | None:
    """The look at a ROS 2 `GeneratedPort`'s servers: its generated components hold each service client as
    `_<action>` and each ROS action client as `_act_<action>` (`.client`: rclpy's client); None when it has
    none of `actions`."""
    wanted = set(actions)
    checks: dict[str, Callable[[], bool]] = {}
    for component in getattr(port, "components", {}).values():
        for attr, value in vars(component).items():
            client: Any = getattr(value, "client", None)
            server_ready = getattr(client, "server_is_ready", None)
            service_ready = getattr(client, "service_is_ready", None)
            if attr.startswith("_act_") and callable(server_ready):
                checks[attr[len("_act_") :]] = server_ready
            elif attr.startswith("_") and callable(service_ready):
                checks[attr[1:]] = service_ready
    checks = {name: check for name, check in checks.items() if name in wanted}
    if not checks:
        return None

    def look() -> dict[str, bool]:
        return {name: bool(check()) for name, check in checks.items()}

    return look


def sim_probe(port: Any, actions: Iterable[str]) -> Probe:
    """The simulated robot's `down` switch: every action's server gone, or every one there."""
    names = list(actions)
    return lambda: dict.fromkeys(names, not port.down)


def probe_of(port: Any, actions: Iterable[str]) -> Probe | None:
    """How to look at `port`'s robot (see the module docstring); None when it cannot be told."""
    from td2adaptor.runtime.ros.simport import SimPort

    if isinstance(port, SimPort):
        return sim_probe(port, actions) if port.watched else None
    if getattr(port, "distro", None) == "ros2":
        return ros2_probe(port, actions)
    return None


class Presence:
    """What the last look saw (`update`) and what follows from it: the status word, the missing actions, and
    whether an invoke of an action is refused (`absent`). Used on the engine's loop only."""

    def __init__(self, robot: str, grace: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.robot = robot
        self.grace = grace
        self.clock = clock
        self.started = clock()
        self.ready: dict[str, bool] | None = None  # None: not looked yet
        self._seen: set[str] = set()  # actions whose server was there once
        self._gone: dict[str, float] = {}  # since when each missing action's server is gone (the loop's clock)

    def update(self, ready: Mapping[str, bool]) -> None:
        now = self.clock()
        self.ready = dict(ready)
        for name, there in ready.items():
            if there:
                self._seen.add(name)
                self._gone.pop(name, None)
            else:
                self._gone.setdefault(name, now)

    def word(self) -> str | None:
        """`present`, `partial` or `absent`; None before the first look."""
        if self.ready is None:
            return None
        there = sum(self.ready.values())
        return PRESENT if there == len(self.ready) else ABSENT if there == 0 else PARTIAL

    def missing(self) -> list[str]:
        return sorted(name for name, there in (self.ready or {}).items() if not there)

    def absent(self, spec: EventSpec) -> str | None:
        """(the engine's gate) Why an invoke of `spec`'s action is not sent now, or None."""
        name = spec.affordance
        if self.ready is None or name is None or self.ready.get(name, True):
            return None
        if name not in self._seen and self.clock() - self.started < self.grace:
            return None  # not discovered yet at start-up: the call waits for its server as before
        return (
            f"not sent: the ROS server of {name} is not there (robot {self.robot}'s ROS side is "
            f"{self.word()}); the robot's status says when it is back"
        )
