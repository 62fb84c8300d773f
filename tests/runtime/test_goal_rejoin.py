"""A ROS action goal in flight outlives its edge node (issue 32): the node that serves the robot next (the same
node started again on its state directory, or another process of a shared fleet) follows the goal on by the id
the server gave it (runtime/engine/goals.py `rejoin`, the port's `GoalRejoin`), instead of ending it `failed`
with its outcome unknown. In process, on the local bus and simulated action servers (`SimActions`, which keep
running while the node is away); the real kill -9 over ROS 2 and mosquitto is test_goal_rejoin_ros2.py.

Checked: the rest of the goal's feedback and its one real terminal event, numbered on past every number the last
run may have used; a query and a cancel of the goal by its id; a goal that ended while no node followed it (its
real end); a goal the server does not know (`failed`, words that say so)."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.engine.ledger import SEQ_BLOCK
from td2adaptor.runtime.ros.simport import SimActions, SimPort, fibonacci
from tests.runtime.edge import Recorder, until
from tests.runtime.rb1 import sim
from tests.runtime.threads_proc import action_model

ROBOT = "fibo_rejoin"
TOPIC = f"td2adaptor/{ROBOT}/MathComponent/fibonacci"


class Node:
    """The robot's simulated action servers (they outlive the edge node) and its edge node, started and stopped
    on one state directory."""

    def __init__(self, state: Path, step: float = 0.05) -> None:
        self.state = state
        self.model = action_model()
        self.actions = SimActions(step=step)
        self.broker = LocalBroker()
        self.app = Recorder(self.broker, [f"{TOPIC}/#"], "rejoin-app")
        self.engine: Engine | None = None

    def start(self, actions: SimActions | None = None, *, watched: bool = False) -> Engine:
        port = SimPort(self.model, sim(robot_id=ROBOT), readers={}, writers={}, actions=actions or self.actions)
        port.watched = watched  # its presence looked at (node/presence.py): the status says `robot`
        config = RuntimeConfig(robot=ROBOT, bus="local", state_dir=str(self.state), call_timeout=2.0)
        self.engine = serve(self.model, port, config, broker=self.broker)
        return self.engine

    def stop(self) -> None:
        if self.engine is not None:
            self.engine.stop()
            self.engine = None

    def send(self, suffix: str, event: dict[str, Any]) -> None:
        self.app.send(TOPIC + suffix, json.dumps(event).encode())

    def feedback(self, correlation: str) -> list[dict[str, Any]]:
        return [e for _, e in self.app.events if e.get("type") == "feedback" and e.get("correlation") == correlation]

    def terminals(self, correlation: str) -> list[dict[str, Any]]:
        return [e for e in self.feedback(correlation) if e["payload"]["terminal"]]

    def ended(self, correlation: str, timeout: float = 20.0) -> dict[str, Any]:
        assert until(lambda: bool(self.terminals(correlation)), timeout), self.feedback(correlation)
        return self.terminals(correlation)[0]

    def close(self) -> None:
        self.stop()
        self.app.close()


def _running(node: Node, correlation: str, count: int) -> bool:
    return sum(e["payload"]["state"] == "running" for e in node.feedback(correlation)) >= count


def test_a_goal_in_flight_is_followed_on_by_its_id_after_a_restart(tmp_path: Path) -> None:
    node = Node(tmp_path)
    try:
        node.start()
        node.send("", {"id": "g-1", "correlation": "g-1", "payload": {"order": 40}})  # 40 steps of 0.05 s
        assert until(lambda: _running(node, "g-1", 3), 20), node.feedback("g-1")
        node.stop()  # the node goes away; the goal goes on in the server
        before = node.feedback("g-1")
        goal = before[0]["payload"]["goal"]
        last = max(e["payload"]["seq"] for e in before)
        time.sleep(0.2)  # a few feedback messages nobody follows
        engine = node.start()
        end = node.ended("g-1")
        after = node.feedback("g-1")[len(before) :]
        assert engine.stats.get("rejoined") == 1 and not engine.stats.get("restart-failed")
        # the rest of the goal's feedback, then its one real end
        assert [e["payload"]["state"] for e in after] == ["running"] * (len(after) - 1) + ["finished"], after
        assert len(after) >= 10, after  # 40 messages in 2 s: most came after the restart
        assert end["payload"]["result"] == "succeeded" and end["payload"]["output"] == {"sequence": fibonacci(40)}
        assert {e["payload"]["goal"] for e in after} == {goal}
        assert after[-2]["payload"]["feedback"] == {"sequence": fibonacci(40)}
        # numbered on past every number the last run may have used: a gap, never a repeat
        seqs = [e["payload"]["seq"] for e in node.feedback("g-1")]
        assert seqs == sorted(set(seqs)), seqs
        assert after[0]["payload"]["seq"] > last + SEQ_BLOCK - 1, (last, after[0]["payload"])
        assert len(node.terminals("g-1")) == 1
        # a second restart has nothing left to do
        node.stop()
        engine = node.start()
        assert not engine.stats.get("rejoined") and len(node.terminals("g-1")) == 1
    finally:
        node.close()


def test_a_goal_followed_on_answers_a_query_and_a_cancel_by_its_id(tmp_path: Path) -> None:
    node = Node(tmp_path)
    try:
        node.start()
        node.send("", {"id": "g-2", "correlation": "g-2", "payload": {"order": 400}})  # 20 s
        assert until(lambda: _running(node, "g-2", 2), 20), node.feedback("g-2")
        node.stop()
        goal = node.feedback("g-2")[0]["payload"]["goal"]
        node.start()
        seen = len(node.feedback("g-2"))
        assert until(lambda: len(node.feedback("g-2")) > seen + 1, 20)  # followed on
        node.send("/query", {"id": "q-1", "correlation": "q-1", "payload": {"goal": goal}})
        node.send("/cancel", {"id": "c-1", "correlation": "c-1", "payload": {"goal": goal}})
        end = node.ended("g-2")
        assert (end["payload"]["state"], end["payload"]["result"]) == ("cancelled", "canceled"), end
        answers = {e["correlation"]: e for _, e in node.app.events if e.get("type") in ("state", "error")}
        assert answers["q-1"]["type"] == "state" and answers["q-1"]["payload"]["state"] == "running", answers
        assert answers["q-1"]["payload"]["goal"] == goal
        assert answers["c-1"]["type"] == "state" and answers["c-1"]["payload"]["goal"] == goal, answers
        assert len(node.terminals("g-2")) == 1
    finally:
        node.close()


def test_a_goal_that_ended_while_no_node_followed_it_gets_its_real_end(tmp_path: Path) -> None:
    node = Node(tmp_path, step=0.02)
    try:
        node.start()
        node.send("", {"id": "g-3", "correlation": "g-3", "payload": {"order": 10}})
        assert until(lambda: _running(node, "g-3", 1), 20), node.feedback("g-3")
        node.stop()
        assert until(lambda: not node.actions._goals, 10)  # it ended in the server meanwhile
        assert not node.terminals("g-3")
        node.start()
        end = node.ended("g-3")
        assert (end["payload"]["state"], end["payload"].get("result")) == ("finished", "succeeded"), end
        assert end["payload"]["output"] == {"sequence": fibonacci(10)}
        assert len(node.terminals("g-3")) == 1
    finally:
        node.close()


def test_a_goal_the_server_does_not_know_ends_failed_saying_so(tmp_path: Path) -> None:
    node = Node(tmp_path)
    try:
        node.start()
        node.send("", {"id": "g-4", "correlation": "g-4", "payload": {"order": 400}})
        assert until(lambda: _running(node, "g-4", 1), 20), node.feedback("g-4")
        node.stop()
        goal = node.feedback("g-4")[0]["payload"]["goal"]
        node.start(SimActions())  # other servers (a robot restarted): they never had the goal
        end = node.ended("g-4")
        payload = end["payload"]
        assert (payload["state"], payload["reason"]) == ("failed", "unreachable"), payload
        words = payload["message"]
        assert words.startswith(f"the edge node restarted while it followed this goal ({goal})"), words
        assert f"the action server does not know goal {goal}" in words and "its outcome is unknown" in words, words
        assert len(node.terminals("g-4")) == 1
    finally:
        node.close()


def test_the_first_status_after_a_restart_counts_the_goal_followed_on_and_says_whether_the_robot_is_there(
    tmp_path: Path,
) -> None:
    """The first `online` status of the restarted node said `missions: 0` (and no `robot`) for 10-30 ms while
    the node followed a goal on: it went out on connecting, before the recovery took the goal up (a new user's
    `fleet status` saw 1, offline, 0, 1). Now the status keeper publishes the first one, after the recovery and
    the first look at the robot."""
    node = Node(tmp_path)
    status = Recorder(node.broker, [f"td2adaptor/{ROBOT}/status"], "status-watch")
    try:
        node.start(watched=True)
        node.send("", {"id": "g-s", "correlation": "g-s", "payload": {"order": 200}})  # 10 s
        assert until(lambda: _running(node, "g-s", 2), 20), node.feedback("g-s")
        node.stop()
        stopped = len(status.events)
        node.start(watched=True)
        status.wait(lambda ev: any(e["payload"]["state"] == "online" for _, e in ev[stopped:]))
        first = next(e["payload"] for _, e in status.events[stopped:] if e["payload"]["state"] == "online")
        assert first["missions"] == 1 and first.get("robot") == "present", first
        node.send(
            "/cancel",
            {"id": "c-s", "correlation": "c-s", "payload": {"goal": node.feedback("g-s")[0]["payload"]["goal"]}},
        )
        assert node.ended("g-s")["payload"]["state"] == "cancelled"
    finally:
        node.close()
        status.close()
