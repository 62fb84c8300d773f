"""The edge node serving a TD action bound to a ROS 1 action, through the bridge, over a real mosquitto.

Real parts only: Debian's rosmaster, rospy and actionlib; the robot is tests/runtime/fibo_ros1.py (an actionlib
ActionServer of test_msgs/Fibonacci, genpy-built from tests/data/actions by tests/ros1/build_actions.py) in its
own process; the rospy adaptor generated from tests.lowering.test_actions.action_td runs in the ROS 1 bridge
(td2adaptor.runtime.ros.bridge, under /usr/bin/python3), the engine and the bus here. Checked as on ROS 2
(test_edge_node_actions_ros2): invoke → acceptance, one feedback event per ROS feedback message, exactly one
terminal event with the result; rejected and aborted with the server's words; query and cancel; the robot
killed mid-goal → failure within the timeout.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import Model
from td2adaptor.model.events import Kind, build_catalog
from td2adaptor.model.wot import WOT_LEVEL, wot_data, wot_specs, wot_topic
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.events import EventValidator
from td2adaptor.runtime.ros.bridge import Ros1Bridge
from td2adaptor.runtime.ros.genport import Layout
from tests import generated
from tests.conftest import REPO
from tests.lowering.test_actions import INTERFACES, action_td
from tests.ros1 import harness
from tests.ros1.harness import Master
from tests.ros2.common import Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, Event
from tests.runtime.edge import CLASS_NAME, feedback
from tests.runtime.fibo_ros2 import ABORT, BURST, SLOW, sequence
from tests.runtime.rb1 import terminal

ROBOT = "fibo_one"
KILLED = "fibo_one_killed"
BRIDGE_KILLED = "fibo_one_bridge"
COMPONENT = "MathComponent"
BUILD_ACTIONS = REPO / "tests" / "ros1" / "build_actions.py"


@pytest.fixture(scope="module")
def build(ros1: None, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path, Path]:
    """The model, the generated rospy package's src/ and the genpy modules of tests/data/actions."""
    base = tmp_path_factory.mktemp("fibo-ros1")
    td = base / "td.json"
    td.write_text(json.dumps(action_td()), encoding="utf-8")
    model, package = generated.generate(
        "rospy", td, base / "pkg", interfaces=[INTERFACES], options=GenOptions(partial=True)
    )
    modules = base / "genpy"
    built = subprocess.run(
        [harness.SYSTEM_PYTHON, str(BUILD_ACTIONS), str(INTERFACES), str(modules)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert built.returncode == 0, built.stderr
    return model, package / "src", modules


def robot_process(master: Master, modules: Path, namespace: str) -> Process:
    script = REPO / "tests" / "runtime" / "fibo_ros1.py"
    process = Process([harness.SYSTEM_PYTHON, str(script), namespace], master.env(modules, REPO))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
    except BaseException:
        process.stop()
        raise
    return process


@pytest.fixture(scope="module")
def fibo_robot(master: Master, build: tuple[Model, Path, Path]) -> Iterator[Process]:
    process = robot_process(master, build[2], ROBOT)
    yield process
    process.stop()


class Edge:
    """The edge node of `robot`: bridge (ROS 1) + engine + mosquitto, and an application recording events."""

    def __init__(self, build: tuple[Model, Path, Path], master: Master, broker: Mosquitto, robot: str, **kw: Any):
        model, src, modules = build
        settings: dict[str, Any] = {"poll_period": 0.1, "call_timeout": 10.0, "mission_timeout": 60.0}
        settings.update(kw)
        self.config = RuntimeConfig(robot=robot, bus=broker.url, property_period=0, state_dir="", **settings)
        self.bridge = Ros1Bridge(
            Layout.of(model),
            model.package_name,
            [(robot, robot)],
            python=harness.SYSTEM_PYTHON,
            pythonpath=[modules, src],
            master_uri=master.uri,
            timeout=self.config.call_timeout,
            environ=master.env(),
        )
        self.bridge.start()
        self.engine = serve(model, self.bridge.port(robot), self.config, distro="ros1")
        self.app = AppClient(broker.url, [f"td2adaptor/{robot}/#"])
        self.catalog = build_catalog(model, "ros1")
        self.validator = EventValidator(self.catalog)
        # what the node sends WoT consumers, per topic: validated with unknown keys forbidden too
        self.wot = {
            topic: (spec, Draft202012Validator(wot_data(spec)))
            for spec in wot_specs(self.catalog)
            if not spec.kind.inbound and (topic := wot_topic(spec, robot)) is not None
        }

    def send(self, suffix: str, event: dict[str, Any]) -> None:
        self.app.send(f"td2adaptor/{self.config.robot}/{COMPONENT}/fibonacci{suffix}", {"source": "test", **event})

    def ended(self, correlation: str, timeout: float = 30.0) -> list[dict[str, Any]]:
        self.app.wait(terminal("feedback", correlation), timeout=timeout)
        self.check(self.app.events)
        return feedback(self.app.events, correlation)

    def answers(self, correlation: str) -> list[dict[str, Any]]:
        def found(events: list[Event]) -> list[dict[str, Any]]:
            return [e for _, e in events if e.get("correlation") == correlation and e.get("type") in ("state", "error")]

        return found(self.app.wait(lambda ev: bool(found(ev)), timeout=10))

    def check(self, events: list[Event]) -> int:
        """Every event and WoT message the node sent conforms to its strict ROS 1 schema; how many WoT messages."""
        wot = 0
        for where, event in events:
            if self.catalog.route(where) is not None or where.endswith("/td"):
                continue  # sent by the test, or the robot's TD
            if f"/{WOT_LEVEL}/" in where:
                assert where in self.wot, where
                assert list(self.wot[where][1].iter_errors(event)) == [], (where, event)
                wot += 1
                continue
            kind = Kind(event["type"])
            spec = self.catalog.find(kind, event.get("affordance") if kind not in (Kind.ERROR, Kind.STATUS) else None)
            assert spec.topic(event["robot"]) == where
            assert self.validator.errors(spec, event) == [], (where, event)
        return wot

    def close(self) -> None:
        self.app.close()
        self.engine.stop()
        self.bridge.close()


def sent_feedback(robot: Process, ns: str, order: int) -> list[list[int]]:
    robot.seen.clear()
    robot.wait_for(lambda e: e.get("event") == "goal" and e.get("ns") == ns and e.get("order") == order, timeout=10)
    robot.seen.clear()
    robot.wait_for(lambda e: e.get("event") == "end" and e.get("ns") == ns, timeout=10)
    return [e["sequence"] for e in robot.seen if e.get("event") == "feedback" and e.get("ns") == ns]


def test_goal_feedback_result_rejected_aborted(
    build: tuple[Model, Path, Path], master: Master, fibo_robot: Process, broker: Mosquitto
) -> None:
    edge = Edge(build, master, broker, ROBOT)
    try:
        edge.send("", {"correlation": "five", "payload": {"order": 5}})
        events = edge.ended("five")
        payloads = [e["payload"] for e in events]
        assert [p["seq"] for p in payloads] == list(range(1, len(payloads) + 1))
        assert [p["terminal"] for p in payloads] == [False] * (len(payloads) - 1) + [True]
        assert payloads[0]["state"] == "queued" and len({p["goal"] for p in payloads}) == 1
        # feedback trails the result (another topic): still `running` with a running word, the end only at the end
        assert [(p["state"], p["result"]) for p in payloads[1:-1]] == [("running", "executing")] * 5, payloads
        assert [p["feedback"]["sequence"] for p in payloads[1:-1]] == sent_feedback(fibo_robot, ROBOT, 5)
        assert len(payloads) == 5 + 2
        last = payloads[-1]
        assert (last["state"], last["result"], last["message"]) == ("finished", "succeeded", "done")
        assert last["output"] == {"sequence": sequence(5)}
        # the WoT form of each feedback event (published after the envelope's), checked too
        edge.app.wait(
            lambda ev: any(
                f"/{WOT_LEVEL}/" in t and e.get("correlationId") == "five" and e.get("terminal") for t, e in ev
            )
        )
        assert edge.check(edge.app.events) >= len(payloads)

        edge.send("", {"correlation": "neg", "payload": {"order": -1}})
        (refused,) = edge.ended("neg")
        assert (refused["payload"]["reason"], refused["payload"]["result"]) == ("rejected", "rejected")
        assert "order must not be negative" in refused["payload"]["message"]

        edge.send("", {"correlation": "abort", "payload": {"order": ABORT}})
        events = edge.ended("abort")
        last = events[-1]["payload"]
        assert [e["payload"]["feedback"]["sequence"] for e in events[1:-1]] == [sequence(1), sequence(2)]
        assert (last["state"], last["reason"], last["result"]) == ("failed", "aborted", "aborted")
        assert last["message"] == f"{ABORT} is unlucky" and last["output"] == {"sequence": sequence(2)}
    finally:
        edge.close()


def test_query_and_cancel(
    build: tuple[Model, Path, Path], master: Master, fibo_robot: Process, broker: Mosquitto
) -> None:
    edge = Edge(build, master, broker, ROBOT)
    try:
        edge.send("", {"correlation": "slow", "payload": {"order": SLOW}})
        edge.app.wait(lambda ev: any("feedback" in e["payload"] for e in feedback(ev, "slow")), timeout=20)
        goal = feedback(edge.app.events, "slow")[0]["payload"]["goal"]
        edge.send("/query", {"correlation": "q", "payload": {"goal": goal}})
        (state,) = edge.answers("q")
        assert (state["payload"]["state"], state["payload"]["result"], state["payload"]["goal"]) == (
            "running",
            "executing",
            goal,
        )
        edge.send("/cancel", {"correlation": "c"})
        events = edge.ended("slow")
        last = events[-1]["payload"]
        assert (last["state"], last["result"], last["message"]) == ("cancelled", "canceled", "canceled on request")
        assert all(e["payload"]["goal"] == goal for e in edge.answers("c"))
    finally:
        edge.close()


def test_robot_killed_mid_goal(build: tuple[Model, Path, Path], master: Master, broker: Mosquitto) -> None:
    robot = robot_process(master, build[2], KILLED)
    edge = Edge(build, master, broker, KILLED, mission_timeout=20.0)
    try:
        edge.send("", {"correlation": "k", "payload": {"order": SLOW}})
        edge.app.wait(lambda ev: any("feedback" in e["payload"] for e in feedback(ev, "k")), timeout=20)
        robot.proc.send_signal(signal.SIGKILL)
        robot.proc.wait(10)
        killed = time.monotonic()
        events = edge.ended("k", timeout=30)
        last = events[-1]["payload"]
        assert last["state"] == "failed" and last["reason"] in ("unreachable", "timeout"), last
        assert not CLASS_NAME.search(last["message"]), last  # was "ServiceUnavailable: service ... (went away ...)"
        assert time.monotonic() - killed < 20.0 + 5.0
        assert sum(1 for e in events if e["payload"]["terminal"]) == 1
    finally:
        edge.close()
        robot.stop()


def test_the_bridge_killed_mid_goal_fails_the_goal_at_once_and_a_new_bridge_runs_the_next(
    build: tuple[Model, Path, Path], master: Master, broker: Mosquitto
) -> None:
    """The ROS 1 bridge's child killed (SIGKILL) while it follows a goal: the parent learns it from the child's
    output ending, and the goal ends `failed`/`unreachable` at once (no query to fail three times, no mission
    timeout), in words; the next goal starts a new child and runs to its end. (A robot of its own: the slow
    goal the dead child sent goes on there.)"""
    robot = robot_process(master, build[2], BRIDGE_KILLED)
    edge = Edge(build, master, broker, BRIDGE_KILLED, mission_timeout=60.0)
    try:
        edge.send("", {"correlation": "b", "payload": {"order": SLOW}})
        edge.app.wait(lambda ev: any("feedback" in e["payload"] for e in feedback(ev, "b")), timeout=20)
        pid = edge.bridge.pid
        assert pid is not None
        os.kill(pid, signal.SIGKILL)
        killed = time.monotonic()
        events = edge.ended("b", timeout=20)
        last = events[-1]["payload"]
        assert (last["state"], last["reason"], last["result"]) == ("failed", "unreachable", "lost"), last
        assert "ROS 1 bridge exited" in last["message"] and not CLASS_NAME.search(last["message"]), last
        assert time.monotonic() - killed < 5.0
        assert sum(1 for e in events if e["payload"]["terminal"]) == 1
        time.sleep(edge.bridge.restart_period)  # the next call restarts the child (at most every restart_period)
        edge.send("", {"correlation": "next", "payload": {"order": 3}})
        events = edge.ended("next", timeout=30)
        assert events[-1]["payload"]["state"] == "finished", events[-1]
        assert edge.bridge.pid not in (None, pid)
    finally:
        edge.close()
        robot.stop()


def test_a_burst_of_a_thousand_feedback_messages_is_relayed_in_order_without_a_gap_or_a_duplicate(
    build: tuple[Model, Path, Path], master: Master, fibo_robot: Process, broker: Mosquitto
) -> None:
    """As on ROS 2: 1,000 feedback messages published back to back ([i] each), through actionlib, the bridge's
    child and its pipe: one feedback event each, in order, none twice, none missing, then the terminal event."""
    edge = Edge(build, master, broker, ROBOT)
    try:
        edge.send("", {"correlation": "burst", "payload": {"order": BURST + 1000}})
        events = edge.ended("burst", timeout=60)
        payloads = [e["payload"] for e in events]
        relayed = [p.get("feedback", {}).get("sequence") for p in payloads[1:-1]]
        missing = sorted(set(range(1, 1001)) - {r[0] for r in relayed if r})
        assert len(relayed) == 1000 and not missing, (len(relayed), missing[:20])
        assert relayed == [[i] for i in range(1, 1001)]
        assert [p["seq"] for p in payloads] == list(range(1, 1003))
        assert (payloads[0]["state"], payloads[-1]["state"]) == ("queued", "finished")
        assert payloads[-1]["output"] == {"sequence": [1000]}
        assert len({e["id"] for e in events}) == len(events) == 1002
    finally:
        edge.close()
