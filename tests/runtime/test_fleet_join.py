"""`Fleet.join` (node/fleet.py), how a shared fleet starts robots: a set starts while another set's start is under
way, a robot is never started twice, robots leave meanwhile, and a start that outlives the fleet's stop leaves
nothing served. Real mosquitto; the robots are simulated (`SimPort`), and one robot's ROS side comes up only when
the test lets it (a slow ROS graph, which a test cannot make slow on purpose otherwise).
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from td2adaptor.runtime.config import RuntimeConfig, load_defaults, robot_config
from td2adaptor.runtime.node.fleet import Changes, Fleet
from td2adaptor.runtime.node.roslink import RosLink
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import until
from tests.runtime.rb1 import rb1_model, sim


class SlowGraph:
    """Grows ports for robots; a set with `slow` in it waits for `go` first. Counts each robot's starts."""

    def __init__(self, slow: str) -> None:
        self.model = rb1_model()
        self.slow = slow
        self.go = threading.Event()
        self.grown: Counter[str] = Counter()

    def grow(self, configs: Sequence[RuntimeConfig]) -> RosLink:
        self.grown.update(c.robot for c in configs)
        if any(c.robot == self.slow for c in configs):
            assert self.go.wait(30)
        return RosLink(ports={c.robot: SimPort(self.model, sim()) for c in configs})


def joining(fleet: Fleet, configs: list[RuntimeConfig]) -> tuple[threading.Thread, Changes]:
    """`fleet.join(configs)` on a thread of its own: the thread and what the join did (once it ended)."""
    out = Changes()

    def run() -> None:
        changes = fleet.join(configs, "file")
        out.added, out.failed = changes.added, changes.failed

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, out


def test_a_set_joins_while_another_sets_start_is_under_way_and_no_robot_starts_twice(
    broker: Mosquitto, tmp_path: Path
) -> None:
    defaults = load_defaults(env={}, overrides={"bus": broker.url, "state_dir": str(tmp_path)})
    graph = SlowGraph("slow")
    fleet = Fleet(graph.model, RosLink(grow=graph.grow), distro="ros2")
    try:
        fleet.join([robot_config(defaults, "old")], "file")
        first, done = joining(fleet, [robot_config(defaults, "slow")])
        assert until(lambda: graph.grown["slow"] == 1, 10)
        # during that start: another set starts (the slow robot, asked again, is not started a second time)
        changes = fleet.join([robot_config(defaults, "slow"), robot_config(defaults, "quick")], "file")
        assert changes.added == ["quick"], changes.describe()
        assert changes.failed == {"slow": "starting or stopping already"}
        assert set(fleet.robots()) == {"old", "quick"}
        assert fleet.remove("old")  # and a robot leaves, without waiting for the slow start either
        assert first.is_alive()  # the slow start is still under way
        graph.go.set()
        first.join(30)
        assert done.added == ["slow"], done.describe()
        assert set(fleet.robots()) == {"quick", "slow"}
        assert graph.grown == Counter({"old": 1, "slow": 1, "quick": 1})
        assert all(e.failure is None for e in fleet.engines())
    finally:
        graph.go.set()
        fleet.stop()


def test_a_start_that_ends_after_the_fleet_stopped_leaves_nothing_served(broker: Mosquitto, tmp_path: Path) -> None:
    defaults = load_defaults(env={}, overrides={"bus": broker.url, "state_dir": str(tmp_path)})
    graph = SlowGraph("slow")
    fleet = Fleet(graph.model, RosLink(grow=graph.grow), distro="ros2")
    try:
        start, done = joining(fleet, [robot_config(defaults, "slow")])
        assert until(lambda: graph.grown["slow"] == 1, 10)
        fleet.stop()  # the process stops during the start
        graph.go.set()
        start.join(30)
        assert not start.is_alive()
        assert done.added == [] and "slow" in done.failed, done.describe()
        assert fleet.robots() == {} and fleet.engines() == []
    finally:
        graph.go.set()
        fleet.stop()


class SlowClose(SimPort):
    """A simulated robot whose port closes only when the test lets it (a slow ROS teardown)."""

    go = threading.Event()

    def close(self) -> None:
        assert self.go.wait(30)


def test_a_robot_leaving_slowly_keeps_no_other_from_joining_and_is_not_started_again_before_it_left(
    broker: Mosquitto, tmp_path: Path
) -> None:
    defaults = load_defaults(env={}, overrides={"bus": broker.url, "state_dir": str(tmp_path)})
    model = rb1_model()
    SlowClose.go = threading.Event()

    def grow(configs: Sequence[RuntimeConfig]) -> RosLink:
        port = {"leaving": SlowClose}
        return RosLink(ports={c.robot: port.get(c.robot, SimPort)(model, sim()) for c in configs})

    fleet = Fleet(model, RosLink(grow=grow), distro="ros2")
    try:
        assert fleet.join([robot_config(defaults, "leaving")], "file").added == ["leaving"]
        removing = threading.Thread(target=fleet.remove, args=("leaving",), daemon=True)
        removing.start()
        assert until(lambda: "leaving" not in fleet.robots(), 10)
        # its port still closes: another robot joins meanwhile; it is not started again, by no way of starting one
        changes = fleet.join([robot_config(defaults, "other"), robot_config(defaults, "leaving")], "file")
        assert changes.added == ["other"], changes.describe()
        assert changes.failed == {"leaving": "starting or stopping already"}
        again = fleet.apply([robot_config(defaults, "leaving")], "admin")
        assert again.failed == {"leaving": "starting or stopping already"}, again.describe()
        assert removing.is_alive()
        SlowClose.go.set()
        removing.join(30)
        assert fleet.join([robot_config(defaults, "leaving")], "file").added == ["leaving"]  # once it left
        assert set(fleet.robots()) == {"other", "leaving"}
    finally:
        SlowClose.go.set()
        fleet.stop()
