"""Presence on ROS 2 counts the servers of each of a robot's services in the node's graph (issue 31's fleet CPU:
asking each client `service_is_ready()` cost 2.6 times as much), and says what the servers say: a robot whose
services are served is there, a service only clients ask for (ours) is not, and a robot whose node stopped is
gone. Real rclpy nodes (the PyPI wheels), std_srvs services."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import td2adaptor
from td2adaptor.runtime.node import presence
from tests.ros2.common import std_td

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain


class Counting:
    """A node whose graph reads are counted (and no client is asked)."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.reads = 0

    def count_services(self, name: str) -> int:
        self.reads += 1
        return int(self.node.count_services(name))


def until(predicate: Any, timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return bool(predicate())


def test_presence_counts_each_services_servers_and_says_what_the_servers_say(ros2_domain: int, tmp_path: Path) -> None:
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
        reads = node.reads
        looks = {ns: probe() for ns, probe in probes.items() if probe is not None}
        assert node.reads - reads == 2 * 2 + 20, node.reads - reads  # one count per service of each robot
        assert looks["graph_b"] == {"trigger": False, "enable": False}, looks["graph_b"]  # ours is a client
        assert not any(looks[f"many_{i}"]["trigger"] for i in range(20))
        robot.destroy_node()  # the robot's node stops cleanly: its servers are gone
        assert until(lambda: probes["graph_a"]() == {"trigger": False, "enable": False})  # type: ignore[misc]
        assert presence.ros2_probe(model, "graph_a", node, ["nothing_of_this_robot"]) is None
    finally:
        rclpy.shutdown(context=context)
