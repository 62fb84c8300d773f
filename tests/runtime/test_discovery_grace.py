"""`run --discover` retires a robot once it has been gone for `discover_grace` (issue 32), counted from the first
look that did not see it. It was counted from the last look that did: when the looks were delayed (the scan also
starts and stops robots, which takes seconds on a loaded machine), a robot gone for a moment was taken as gone
for the whole delay and retired at once (a clean-clone CI run: 0.16 s after it stopped, with a grace of 1 s)."""

from __future__ import annotations

from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.node.fleet import Changes
from td2adaptor.runtime.node.graphwatch import Discovery, Signature


class Fleet:
    """The discovered robots a fleet serves (what `Discovery` applies)."""

    def __init__(self) -> None:
        self.served: dict[str, RuntimeConfig] = {}

    def robots(self, origin: str | None = None) -> dict[str, RuntimeConfig]:
        return dict(self.served)

    def origin(self, robot: str) -> str | None:
        return "discovery" if robot in self.served else None

    def apply(self, configs: list[RuntimeConfig], origin: str) -> Changes:
        wanted = {c.robot: c for c in configs}
        changes = Changes(added=sorted(set(wanted) - set(self.served)), removed=sorted(set(self.served) - set(wanted)))
        self.served = wanted
        return changes


class Graph:
    name = "test"

    def __init__(self) -> None:
        self.shown: set[str] = set()

    def robots(self, sig: Signature, known: set[str]) -> set[str]:
        return set(self.shown)


def test_a_robot_is_retired_a_grace_after_the_first_look_that_missed_it_however_late_the_looks_come() -> None:
    now = [0.0]
    fleet, graph = Fleet(), Graph()
    discovery = Discovery(
        fleet,  # type: ignore[arg-type]
        graph,
        Signature(("trigger",), (), ()),
        lambda rid, ns: RuntimeConfig(robot=rid, namespace=ns, state_dir=""),
        grace=1.0,
        clock=lambda: now[0],
    )
    graph.shown = {"belt_a"}
    discovery.scan()
    assert set(fleet.served) == {"belt_a"}
    graph.shown = set()  # it goes; the next look comes late (5 s: the scan was busy)
    now[0] = 5.0
    discovery.scan()
    assert set(fleet.served) == {"belt_a"}, "retired at the first look that missed it, with no grace at all"
    now[0] = 5.6
    discovery.scan()
    assert set(fleet.served) == {"belt_a"}  # gone for 0.6 s as far as any look knows
    now[0] = 6.0
    discovery.scan()
    assert fleet.served == {}  # gone for the grace
    # back, then missed by one look only: it stays
    graph.shown = {"belt_a"}
    now[0] = 7.0
    discovery.scan()
    graph.shown = set()
    now[0] = 7.5
    discovery.scan()
    graph.shown = {"belt_a"}
    now[0] = 8.6
    discovery.scan()
    assert set(fleet.served) == {"belt_a"}
