"""`run --discover` on ROS 2 reads the graph when its nodes change, not only every period (issue 32: a robot added
to a fleet is served within 2 s, and a robot found only at the next look waited for it). Real rclpy (the PyPI
wheels): the edge node's graph node in one context, the robot's node, serving a std_srvs service, in another (each
context is a DDS participant of its own, as another process's would be)."""

from __future__ import annotations

import threading
import time
from typing import Any

from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.node.fleet import Changes
from td2adaptor.runtime.node.graphwatch import Discovery, Ros2Graph, Signature

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

#: far longer than the test waits for the robot: only a look the graph's change caused can find it in time
PERIOD = 60.0
#: the robot's node is made after the first look; found within this (DDS discovery of a participant in this
#: process, on 2 busy cores) by a look the change woke, and never by the periodic one
FOUND_WITHIN = 15.0


class Robots:
    """What discovery hands its robots to: kept here, with when each was first handed (the process's fleet)."""

    def __init__(self) -> None:
        self.served: dict[str, RuntimeConfig] = {}
        self.first: dict[str, float] = {}
        self.lock = threading.Lock()

    def robots(self, origin: str | None = None) -> dict[str, RuntimeConfig]:
        with self.lock:
            return dict(self.served)

    def origin(self, robot: str) -> str | None:
        with self.lock:
            return "discovery" if robot in self.served else None

    def apply(self, configs: list[RuntimeConfig], origin: str) -> Changes:
        with self.lock:
            added = [c.robot for c in configs if c.robot not in self.served]
            self.served = {c.robot: c for c in configs}
            for robot in added:
                self.first.setdefault(robot, time.monotonic())
        return Changes(added=added)


def test_a_robot_that_appears_in_the_ros2_graph_is_found_at_once_not_at_the_next_period(ros2_domain: int) -> None:
    import rclpy
    from rclpy.context import Context
    from std_srvs.srv import Trigger

    edge, robot = Context(), Context()
    rclpy.init(context=edge)
    rclpy.init(context=robot)
    graph_node = rclpy.create_node("gw_edge_graph", context=edge, start_parameter_services=False)
    fleet = Robots()
    sig = Signature(services=("gw_ping",), actions=(), published=())
    discovery = Discovery(
        fleet,
        Ros2Graph(graph_node),
        sig,
        lambda rid, ns: RuntimeConfig(robot=rid, namespace=ns),
        grace=5.0,
        period=PERIOD,
    )
    node: Any = None
    try:
        discovery.start()
        deadline = time.monotonic() + 10
        while discovery.scans < 1 and time.monotonic() < deadline:  # the first look, at the start: nothing there
            time.sleep(0.02)
        assert discovery.scans >= 1 and not fleet.served
        appeared = time.monotonic()
        node = rclpy.create_node("gw_robot", namespace="/gw_a", context=robot, start_parameter_services=False)
        node.create_service(Trigger, "gw_ping", lambda _request, response: response)
        deadline = appeared + FOUND_WITHIN
        while "gw_a" not in fleet.served and time.monotonic() < deadline:
            time.sleep(0.02)
        assert "gw_a" in fleet.served, f"not found within {FOUND_WITHIN} s (the period is {PERIOD} s)"
        print(f"appeared -> found: {fleet.first['gw_a'] - appeared:.2f} s")
        # the graph is idle now: looks are not run back to back (the change woke a few, not a poll)
        scans = discovery.scans
        time.sleep(1.0)
        assert discovery.scans - scans <= 2, discovery.scans - scans
    finally:
        discovery.stop()
        if node is not None:
            node.destroy_node()
        graph_node.destroy_node()
        rclpy.shutdown(context=robot)
        rclpy.shutdown(context=edge)


class Nodes:
    """A graph whose nodes the test changes, its readings counted (the scheduling of the looks alone, no ROS)."""

    name = ""

    def __init__(self) -> None:
        self.nodes: frozenset[tuple[str, str]] = frozenset()
        self.looks: list[float] = []

    def stamp(self) -> frozenset[tuple[str, str]]:
        return self.nodes

    def robots(self, sig: Signature, known: set[str]) -> set[str]:
        self.looks.append(time.monotonic())
        return set()


def test_a_change_of_the_graphs_nodes_makes_one_look_at_once_and_two_after_it_and_no_change_none() -> None:
    graph = Nodes()
    sig = Signature(services=("gw_ping",), actions=(), published=())
    discovery = Discovery(Robots(), graph, sig, lambda rid, ns: RuntimeConfig(robot=rid), grace=5.0, period=PERIOD)
    try:
        discovery.start()
        deadline = time.monotonic() + 10
        while not graph.looks and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.5)  # glances that see no change
        assert len(graph.looks) == 1, graph.looks
        changed = time.monotonic()
        graph.nodes = frozenset({("gw_robot", "/gw_b")})
        time.sleep(1.5)
        after = [t - changed for t in graph.looks[1:]]
        # at once (the next glance), then 0.1 and 0.3 s later (fewer when a look was late and two fell due together);
        # never a second look at once, nor a look without a change
        assert 1 <= len(after) <= 3 and after[0] < 1.0, after
    finally:
        discovery.stop()
