"""Presence on ROS 2 reads what each node of the graph serves once for all the robots of the node, and counts
the servers of a name no node was read serving (issue 31's fleet CPU: a count per name of every robot, a scan
of the whole graph cache each, cost the looks of 100 RB-1s a tenth of a core), and says what the servers say:
a robot whose services are served is there, a service only clients ask for (ours) is not, a robot whose node
stopped is gone, and a server whose node shares its name with another node (a node restarted under its old
name while the killed one is still in the graph) is there. Real rclpy nodes (the PyPI wheels), std_srvs
services."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Any

import td2adaptor
from td2adaptor.runtime.node import presence
from tests.ros2.common import std_td

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain


class Counting:
    """A node whose graph reads are counted (and no client is asked): counts of one name's servers (`reads`),
    reads of the graph's nodes (`sweeps`) and of what one node serves (`by_node`)."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.reads = self.sweeps = self.by_node = 0

    def count_services(self, name: str) -> int:
        self.reads += 1
        return int(self.node.count_services(name))

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        self.sweeps += 1
        return list(self.node.get_node_names_and_namespaces())

    def get_service_names_and_types_by_node(self, name: str, namespace: str) -> list[tuple[str, list[str]]]:
        self.by_node += 1
        return list(self.node.get_service_names_and_types_by_node(name, namespace))


def until(predicate: Any, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return bool(predicate())


def test_presence_reads_the_graph_once_counts_what_no_node_serves_and_says_what_the_servers_say(
    ros2_domain: int, tmp_path: Path, monkeypatch: Any
) -> None:
    import rclpy
    from rclpy.context import Context
    from std_srvs.srv import SetBool, Trigger

    td = tmp_path / "td.json"
    td.write_text(json.dumps(std_td(sensors=False)), encoding="utf-8")
    model = td2adaptor.compile(td).model
    assert model is not None
    context = Context()
    rclpy.init(context=context)
    try:
        robot = rclpy.create_node("std_robot_sim", namespace="/graph_a", context=context)
        robot.create_service(Trigger, "/graph_a/trigger", lambda _q, s: s)
        robot.create_service(SetBool, "/graph_a/enable", lambda _q, s: s)
        edge = rclpy.create_node("edge", context=context)
        edge.create_client(Trigger, "/graph_b/trigger")  # a client only: its service is in the plain list
        node = Counting(edge)
        probes = {ns: presence.ros2_probe(model, ns, node, ["trigger", "enable"]) for ns in ("graph_a", "graph_b")}
        probes.update({f"many_{i}": presence.ros2_probe(model, f"many_{i}", node, ["trigger"]) for i in range(20)})
        assert all(p is not None for p in probes.values())
        assert until(lambda: probes["graph_a"]() == {"trigger": True, "enable": True})  # type: ignore[misc]
        monkeypatch.setattr(presence, "GRAPH_FRESH", 60.0, raising=False)  # one read serves every look below
        getattr(presence, "_graphs", {}).clear()
        reads, sweeps = node.reads, node.sweeps
        looks = {ns: probe() for ns, probe in probes.items() if probe is not None}
        assert node.sweeps - sweeps == 1, node.sweeps - sweeps  # one read of the graph for all the robots
        assert node.reads - reads == 2 + 20, node.reads - reads  # a count for each name no node serves only
        monkeypatch.setattr(presence, "GRAPH_FRESH", 0.0, raising=False)
        presence._graphs.clear()  # each look below reads the graph again
        assert looks["graph_b"] == {"trigger": False, "enable": False}, looks["graph_b"]  # ours is a client
        assert not any(looks[f"many_{i}"]["trigger"] for i in range(20))
        robot.destroy_node()  # the robot's node stops cleanly: its servers are gone
        assert until(lambda: probes["graph_a"]() == {"trigger": False, "enable": False})  # type: ignore[misc]
        assert presence.ros2_probe(model, "graph_a", node, ["nothing_of_this_robot"]) is None
    finally:
        rclpy.shutdown(context=context)


def test_a_fleet_that_is_there_costs_one_read_of_the_graph_and_no_count(
    ros2_domain: int, tmp_path: Path, monkeypatch: Any
) -> None:
    """20 robots whose servers are all there: their looks read the graph once (a read by node for each of its
    nodes) and count no name's servers (before: one count per service of each robot, 2 x 20)."""
    import rclpy
    from rclpy.context import Context
    from std_srvs.srv import SetBool, Trigger

    td = tmp_path / "td.json"
    td.write_text(json.dumps(std_td(sensors=False)), encoding="utf-8")
    model = td2adaptor.compile(td).model
    assert model is not None
    context = Context()
    rclpy.init(context=context)
    try:
        robots = []  # kept: a node no longer referred to is destroyed
        for i in range(20):
            robot = rclpy.create_node("std_robot_sim", namespace=f"/fleet_{i}", context=context)
            robots.append(robot)
            robot.create_service(Trigger, f"/fleet_{i}/trigger", lambda _q, s: s)
            robot.create_service(SetBool, f"/fleet_{i}/enable", lambda _q, s: s)
        node = Counting(rclpy.create_node("edge", context=context))
        probes = [presence.ros2_probe(model, f"fleet_{i}", node, ["trigger", "enable"]) for i in range(20)]
        assert all(until(lambda p=p: all(p().values())) for p in probes if p is not None)
        monkeypatch.setattr(presence, "GRAPH_FRESH", 60.0, raising=False)  # one read serves every look below
        getattr(presence, "_graphs", {}).clear()
        reads, sweeps, by_node = node.reads, node.sweeps, node.by_node
        looks = [probe() for probe in probes if probe is not None]
        assert looks == [{"trigger": True, "enable": True}] * 20, looks
        assert (node.reads - reads, node.sweeps - sweeps) == (0, 1), (node.reads - reads, node.sweeps - sweeps)
        # one read by node of each node of the graph: the 20 robots' nodes, ours, and any other test's of this
        # worker's domain still running (a simulation a session keeps)
        graph = len(set(node.node.get_node_names_and_namespaces()))
        assert graph >= 21 and node.by_node - by_node == graph, (node.by_node - by_node, graph)
    finally:
        rclpy.shutdown(context=context)


def test_a_server_whose_node_shares_its_name_with_another_node_is_there(ros2_domain: int, tmp_path: Path) -> None:
    """A robot's node restarted under its old name while the killed one is still in the graph (until its lease
    ends): two nodes of one name, in two processes (here two contexts: two DDS participants). A read by node
    finds one of them only; the look still sees the servers of the other, in either order of the two."""
    import rclpy
    from rclpy.context import Context
    from std_srvs.srv import SetBool, Trigger

    td = tmp_path / "td.json"
    td.write_text(json.dumps(std_td(sensors=False)), encoding="utf-8")
    model = td2adaptor.compile(td).model
    assert model is not None
    first, second = Context(), Context()
    rclpy.init(context=first)
    rclpy.init(context=second)
    try:
        robots = []  # kept: a node no longer referred to is destroyed
        for namespace, serving in (("twin_a", second), ("twin_b", first)):
            for context in (first, second):  # the same node name in both participants; one of them serves
                robot = rclpy.create_node("std_robot_sim", namespace=f"/{namespace}", context=context)
                robots.append(robot)
                robot.create_service(SetBool, f"/{namespace}/enable", lambda _q, s: s)
                if context is serving:
                    robot.create_service(Trigger, f"/{namespace}/trigger", lambda _q, s: s)
        node = Counting(rclpy.create_node("edge", context=first))
        probes = {ns: presence.ros2_probe(model, ns, node, ["trigger", "enable"]) for ns in ("twin_a", "twin_b")}
        for namespace, probe in probes.items():
            assert probe is not None
            assert until(lambda p=probe: p() == {"trigger": True, "enable": True}), (namespace, probe())
    finally:
        rclpy.shutdown(context=second)
        rclpy.shutdown(context=first)


class SlowGraph:
    """A graph of `nodes` nodes whose every read by node takes `cost` seconds of the test's clock (a graph of
    thousands of nodes, whose reads grow with its square, without starting them)."""

    def __init__(self, nodes: int, cost: float) -> None:
        self.now, self.nodes, self.cost, self.sweeps = 0.0, nodes, cost, 0

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        self.sweeps += 1
        return [("sim", f"/r{i}") for i in range(self.nodes)]

    def get_service_names_and_types_by_node(self, _name: str, namespace: str) -> list[tuple[str, list[str]]]:
        self.now += self.cost
        return [(f"{namespace}/trigger", ["std_srvs/srv/Trigger"])]


def test_a_graph_whose_read_is_slow_is_read_at_most_a_tenth_of_the_time() -> None:
    """A read serves `GRAPH_FRESH` (0.25 s), or ten times what it took when that is longer: a 1,000-node graph
    read in 0.1 s is read again after 1 s, not 4 times a second (40 % of a core)."""
    quick, slow = SlowGraph(10, 0.0001), SlowGraph(1000, 0.0001)
    for graph in (quick, slow):
        clock = lambda g=graph: g.now  # noqa: E731
        assert "/r3/trigger" in presence.graph_served(graph, clock)
        start = graph.now
        for step in (0.2, 0.5, 0.8, 1.1):
            graph.now = start + step
            presence.graph_served(graph, clock)
    assert quick.sweeps == 4, quick.sweeps  # at 0, 0.5, 0.8 and 1.1 s: each 0.25 s after the last read
    assert slow.sweeps == 2, slow.sweeps  # at 0 and 1.1 s: the first read took 0.1 s


class HeldGraph(SlowGraph):
    """A graph whose reads by node, once `hold` is cleared, wait until it is set again (a read under way)."""

    def __init__(self) -> None:
        super().__init__(3, 0.0)
        self.hold = threading.Event()
        self.hold.set()
        self.reading = threading.Event()

    def get_service_names_and_types_by_node(self, name: str, namespace: str) -> list[tuple[str, list[str]]]:
        self.reading.set()
        assert self.hold.wait(10.0)
        return super().get_service_names_and_types_by_node(name, namespace)


def test_a_look_does_not_wait_for_a_read_of_the_graph_under_way_but_takes_the_last_one() -> None:
    """Looks run on the call pool, whose threads make the robots' calls: while one look reads the graph, the
    others take the last read at once instead of each waiting for it (or reading it again)."""
    graph = HeldGraph()
    clock = lambda: graph.now  # noqa: E731
    first = presence.graph_served(graph, clock)
    graph.now = 1.0  # the first read is stale: the next look reads again
    graph.hold.clear()
    reader = threading.Thread(target=presence.graph_served, args=(graph, clock))
    reader.start()
    try:
        assert graph.reading.wait(10.0)
        started = time.monotonic()
        assert presence.graph_served(graph, clock) == first  # the last read, at once
        assert time.monotonic() - started < 1.0
        assert graph.sweeps == 2, graph.sweeps
    finally:
        graph.hold.set()
        reader.join(10.0)
    assert presence.graph_served(graph, clock) == first and graph.sweeps == 2  # the new read serves now
