"""A ROS 1 action goal in flight outlives its edge node (issue 32), for real: Debian's rosmaster, rospy and
actionlib, the robot tests/runtime/fibo_ros1.py (an actionlib ActionServer) in its own process, the generated
rospy package in the ROS 1 bridge, the engine here over a real mosquitto. The edge node (engine and bridge) goes
away mid-goal and comes back on the same state directory: it follows the goal on by its id (the generated
`rejoin_<action>`, through the bridge's `rejoin_goal`), as on ROS 2 (test_goal_rejoin_ros2.py): the rest of
the goal's feedback and its one real end; a goal that ended while no node followed it ends as its status says
(actionlib sent its result once, to nobody)."""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import Any

from td2adaptor.model import Model
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.ros.bridge import Ros1Bridge
from td2adaptor.runtime.ros.genport import Layout
from tests.ros1 import harness
from tests.ros1.harness import Master
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, Event
from tests.runtime.edge import feedback
from tests.runtime.fibo_ros2 import sequence
from tests.runtime.rb1 import terminal
from tests.runtime.test_edge_node_actions_ros1 import build, robot_process

__all__ = ["build"]  # the generated package's fixture, shared with test_edge_node_actions_ros1

COMPONENT = "MathComponent"


class Node:
    """The edge node of `robot` (the ROS 1 bridge and the engine) on a state directory, started and stopped."""

    def __init__(self, build: tuple[Model, Path, Path], master: Master, broker: Mosquitto, robot: str, state: Path):
        self.build, self.master, self.robot = build, master, robot
        self.config = RuntimeConfig(
            robot=robot, bus=broker.url, property_period=0, state_dir=str(state), call_timeout=10.0
        )
        self.bridge: Ros1Bridge | None = None
        self.engine: Engine | None = None

    def start(self) -> Engine:
        model, src, modules = self.build
        self.bridge = Ros1Bridge(
            Layout.of(model),
            model.package_name,
            [(self.robot, self.robot)],
            python=harness.SYSTEM_PYTHON,
            pythonpath=[modules, src],
            master_uri=self.master.uri,
            timeout=self.config.call_timeout,
            environ=self.master.env(),
        )
        self.bridge.start()
        self.engine = serve(model, self.bridge.port(self.robot), self.config, distro="ros1")
        return self.engine

    def stop(self) -> None:
        if self.engine is not None:
            self.engine.stop()
            self.engine = None
        if self.bridge is not None:
            self.bridge.close()
            self.bridge = None


def send_goal(app: AppClient, robot: str, order: int) -> str:
    event_id = uuid.uuid4().hex
    topic = f"td2adaptor/{robot}/{COMPONENT}/fibonacci"
    app.send(topic, {"id": event_id, "correlation": event_id, "source": "test", "payload": {"order": order}})
    return event_id


def running(events: list[Event], correlation: str, count: int) -> bool:
    return sum(e["payload"]["state"] == "running" for e in feedback(events, correlation)) >= count


def once(events: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return list({e["id"]: e for e in events}.values())


class Rig:
    """The robot's process, its edge node on a state directory and the application that watches its events."""

    def __init__(self, build: tuple[Model, Path, Path], master: Master, broker: Mosquitto, robot: str, state: Path):
        self.build, self.master, self.name = build, master, robot
        self.robot = robot_process(master, build[2], robot)
        self.node = Node(build, master, broker, robot, state)
        self.app = AppClient(broker.url, [f"td2adaptor/{robot}/#"])

    def goal(self, order: int, count: int) -> str:
        """A goal sent once the node is started, seen `running` `count` times."""
        event_id = send_goal(self.app, self.name, order)
        self.app.wait(lambda ev: running(ev, event_id, count), timeout=30)
        return event_id

    def restart_robot(self) -> None:
        """The robot restarts: its new action server never had the goals of the old one."""
        self.robot.stop()
        self.robot = robot_process(self.master, self.build[2], self.name)

    def end(self, event_id: str) -> dict[str, Any]:
        """The goal's one terminal event, once it came."""
        self.app.wait(terminal("feedback", event_id), timeout=60)
        ends = [e["payload"] for e in once(feedback(self.app.events, event_id)) if e["payload"]["terminal"]]
        assert len(ends) == 1, ends
        return ends[0]

    def close(self) -> None:
        self.node.stop()
        self.robot.stop()
        self.app.close()


def test_a_goal_in_flight_is_followed_on_by_the_node_started_again(
    build: tuple[Model, Path, Path], master: Master, broker: Mosquitto, tmp_path: Path
) -> None:
    rig = Rig(build, master, broker, "rejoin_one", tmp_path / "state")
    node, app = rig.node, rig.app
    try:
        node.start()
        event_id = rig.goal(200, 3)  # 10 s
        node.stop()  # the node goes away; the goal goes on in the server
        before = len(once(feedback(app.events, event_id)))
        assert not any(e["payload"]["terminal"] for e in feedback(app.events, event_id))
        engine = node.start()
        app.wait(terminal("feedback", event_id), timeout=60)
        assert engine.stats.get("rejoined") == 1
        events = once(feedback(app.events, event_id))
        seqs = [e["payload"]["seq"] for e in events]
        assert seqs == sorted(set(seqs)), seqs
        states = [e["payload"]["state"] for e in events]
        assert states[0] == "queued" and states[-1] == "finished" and set(states[1:-1]) == {"running"}, states
        assert len(events) - before >= 10, states  # the rest of its feedback
        end = events[-1]["payload"]
        assert end["result"] == "succeeded" and end["output"] == {"sequence": sequence(40)}, end
        assert sum(e["payload"]["terminal"] for e in events) == 1
    finally:
        rig.close()


def test_a_goal_that_ended_while_no_node_followed_it_ends_as_its_status_says(
    build: tuple[Model, Path, Path], master: Master, broker: Mosquitto, tmp_path: Path
) -> None:
    rig = Rig(build, master, broker, "rejoin_two", tmp_path / "state")
    try:
        rig.node.start()
        event_id = rig.goal(20, 1)  # 1 s
        rig.node.stop()
        rig.robot.wait_for(lambda e: e.get("event") == "end" and e.get("ns") == "rejoin_two", timeout=30)
        rig.node.start()  # within actionlib's status_list_timeout (5 s) of the end
        end = rig.end(event_id)
        assert (end["state"], end.get("result")) == ("finished", "succeeded"), end
    finally:
        rig.close()


def test_a_goal_whose_server_restarted_meanwhile_ends_failed_saying_so(
    build: tuple[Model, Path, Path], master: Master, broker: Mosquitto, tmp_path: Path
) -> None:
    rig = Rig(build, master, broker, "rejoin_three", tmp_path / "state")
    try:
        rig.node.start()
        event_id = rig.goal(400, 1)  # 20 s
        goal = feedback(rig.app.events, event_id)[0]["payload"]["goal"]
        rig.node.stop()
        rig.restart_robot()
        rig.node.start()
        end = rig.end(event_id)
        assert (end["state"], end["reason"]) == ("failed", "unreachable"), end
        words = end["message"]
        assert words.startswith(f"the edge node restarted while it followed this goal ({goal})"), words
        assert f"the action server does not know goal {goal}" in words and words.endswith("unknown"), words
        # the words docs/wot.md quotes, the same as on ROS 2 (before: "... on failed: /ns/fibonacci failed: the ...")
        assert words.endswith(
            f"), and following it on failed: the action server does not know goal {goal}: its outcome is unknown"
        ), words
    finally:
        rig.close()
