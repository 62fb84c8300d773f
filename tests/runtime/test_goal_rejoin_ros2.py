"""A ROS 2 action goal in flight outlives its edge node (issue 32), for real: `td2adaptor run` processes serving a
real rclpy ActionServer (tests/runtime/fibo_ros2.py, its own process) over a real mosquitto, killed with kill -9
while the goal runs. The node that serves the robot next follows the goal on by its id (the generated
`rejoin_<action>`: feedback and status are broadcast to every client, and any client may ask a goal's result):

* the same node started again on its state directory: the rest of the goal's feedback and its one `finished`;
* a goal that ended while no node followed it: the restarted node publishes its real end (the server still
  has its result);
* a goal that ended before the kill: a query and a cancel of it by its id are answered with its end (the ledger's);
* a robot whose action server restarted meanwhile (it does not know the goal): `failed`, with words that say so;
* a shared fleet (`run --share`, each process with a state directory of its own, as on two hosts): the process
  that takes the robot over after its owner's kill -9 follows the goal on from the admitted entries.
"""

from __future__ import annotations

import json
import sys
import time
import uuid
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.model import Model
from td2adaptor.runtime.events import now_rfc3339
from tests.lowering.test_actions import INTERFACES, action_td
from tests.ros2 import env
from tests.ros2.common import Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, Event
from tests.runtime.edge import RunProcess, feedback, until
from tests.runtime.fibo_ros2 import sequence
from tests.runtime.rb1 import terminal
from tests.runtime.rclpy_robot import generate_rclpy

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

#: feedback messages of the long goal, STEP (0.05 s) apart: 20 s, longer than a kill and a start take (loaded)
LONG = 400


@pytest.fixture(scope="module")
def fibo_run(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Model, Path, Path]:
    """The model, its TD's file and the generated rclpy adaptor's source folder (for `--package-path`)."""
    base = tmp_path_factory.mktemp("fibo-rejoin")
    model, src, _ = generate_rclpy(action_td(), INTERFACES, base)
    return model, base / "td.json", src


def robot_process(*namespaces: str) -> Process:
    process = Process([sys.executable, "-m", "tests.runtime.fibo_ros2", *namespaces], env.child_env([]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
    except BaseException:
        process.stop()
        raise
    return process


@pytest.fixture
def robots(request: pytest.FixtureRequest, ros2_domain: int) -> Iterator[Process]:
    process = robot_process(*request.param)
    yield process
    process.stop()


def goal_topic(robot: str) -> str:
    return f"td2adaptor/{robot}/MathComponent/fibonacci"


def run_args(build: tuple[Model, Path, Path], config: Path, *more: str) -> list[str]:
    model, td, src = build
    args = [str(td), "-I", str(INTERFACES), "--config", str(config), "--package", model.package_name]
    return [*args, "--package-path", str(src), *more]


def node_config(path: Path, broker: Mosquitto, state: Path, robots: dict[str, str], fleet: str = "") -> Path:
    lines = [f"bus: {broker.url}", "property_period: 0", "call_timeout: 5", "mission_timeout: 120"]
    lines.append(f"state_dir: {state}")
    if fleet:
        lines.append(f"fleet: {fleet}")
    lines += ["robots:", *(f"  - {{robot: {r}, namespace: {ns}}}" for r, ns in robots.items())]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def goals_answered(app: AppClient, robot: str, timeout: float = 60.0) -> None:
    """Wait until the robot's action server answers a goal through the edge node (a negative order is rejected:
    nothing runs). A ROS 2 service can be discovered before its server matched the client's response reader;
    the first answers may then be lost."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        correlation = f"probe-{uuid.uuid4().hex[:8]}"
        app.send(goal_topic(robot), {"id": correlation, "correlation": correlation, "payload": {"order": -1}})
        app.wait(terminal("feedback", correlation), timeout=30)
        end = [e for e in feedback(app.events, correlation) if e["payload"]["terminal"]][0]["payload"]
        if end.get("result") == "rejected":
            return
    raise AssertionError("the action server never answered a goal through the edge node")


def start_goal(app: AppClient, robot: str, order: int = LONG) -> str:
    event_id = uuid.uuid4().hex
    app.send(
        goal_topic(robot), {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": {"order": order}}
    )
    return event_id


def running(events: list[Event], correlation: str, count: int = 3) -> bool:
    return sum(e["payload"]["state"] == "running" for e in feedback(events, correlation)) >= count


def check_followed_on(events: list[dict[str, Any]], before: int, order: int) -> dict[str, Any]:
    """The goal's events: numbered strictly upwards (a gap allowed, never a repeat), the rest of its feedback after
    the kill (`before` events came before it), its one terminal event `finished` with the server's result."""
    once = list({e["id"]: e for e in events}.values())  # a QoS 1 redelivery repeats an event, never adds one
    seqs = [e["payload"]["seq"] for e in once]
    assert seqs == sorted(set(seqs)), seqs
    states = [e["payload"]["state"] for e in once]
    assert states[0] == "queued" and states[-1] == "finished" and set(states[1:-1]) == {"running"}, states
    assert [e["payload"]["terminal"] for e in once].count(True) == 1
    after = once[before:]
    assert len(after) >= 10, [e["payload"] for e in after]  # the rest of its feedback, after the kill
    assert len({e["payload"]["goal"] for e in once}) == 1
    end = once[-1]["payload"]
    assert end["result"] == "succeeded" and end["output"] == {"sequence": sequence(min(order, 40))}, end
    return end


class Restarting:
    """One robot's `td2adaptor run` on a state directory, killed with kill -9 mid-goal and started again, and the
    application that watches the robot's events."""

    def __init__(self, build: tuple[Model, Path, Path], broker: Mosquitto, tmp_path: Path, robot: str) -> None:
        self.build, self.robot = build, robot
        self.config = node_config(tmp_path / "node.yaml", broker, tmp_path / "state", {robot: robot})
        self.environ = env.child_env([])
        self.app = AppClient(broker.url, [f"td2adaptor/{robot}/#"], client_id=f"{robot}-app")
        self.runs = [RunProcess(run_args(build, self.config), env=self.environ)]

    def ready(self) -> None:
        """The node is ready and the robot's action server answers goals through it."""
        self.runs[-1].wait_ready()
        goals_answered(self.app, self.robot)

    def goal(self, order: int, count: int) -> str:
        """A goal sent and seen `running` `count` times."""
        event_id = start_goal(self.app, self.robot, order)
        self.app.wait(lambda ev: running(ev, event_id, count), timeout=30)
        return event_id

    def kill(self) -> None:
        self.runs[-1].proc.kill()
        self.runs[-1].proc.wait(10)

    def again(self) -> RunProcess:
        run = RunProcess(run_args(self.build, self.config), env=self.environ)
        self.runs.append(run)
        run.wait_ready()
        return run

    def ends(self, event_id: str) -> list[dict[str, Any]]:
        """The goal's terminal events once one came, told apart by content (a redelivery repeats one)."""
        self.app.wait(terminal("feedback", event_id), timeout=60)
        ends = [e["payload"] for e in feedback(self.app.events, event_id) if e["payload"]["terminal"]]
        assert len({json.dumps(p, sort_keys=True) for p in ends}) == 1, ends
        return ends

    def close(self) -> None:
        for run in self.runs:
            run.close()
        self.app.close()


@pytest.mark.parametrize("robots", [("rejoin_a",)], indirect=True)
def test_a_goal_in_flight_is_followed_on_by_the_restarted_node(
    fibo_run: tuple[Model, Path, Path], robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    rig = Restarting(fibo_run, broker, tmp_path, "rejoin_a")
    try:
        rig.ready()
        event_id = rig.goal(LONG, 3)
        rig.kill()
        before = len({e["id"] for e in feedback(rig.app.events, event_id)})
        assert not any(e["payload"]["terminal"] for e in feedback(rig.app.events, event_id))

        started = time.monotonic()
        again = rig.again()
        assert until(lambda: len({e["id"] for e in feedback(rig.app.events, event_id)}) > before, 60)
        print(f"start again -> the goal's feedback relayed again: {time.monotonic() - started:.2f} s")
        rig.ends(event_id)
        check_followed_on(feedback(rig.app.events, event_id), before, LONG)
        assert "following fibonacci goal" in again.output(), again.output()[-3000:]
    finally:
        rig.close()


@pytest.mark.parametrize("robots", [("rejoin_b",)], indirect=True)
def test_a_goal_that_ended_while_no_node_followed_it_gets_its_real_end(
    fibo_run: tuple[Model, Path, Path], robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    rig = Restarting(fibo_run, broker, tmp_path, "rejoin_b")
    try:
        rig.ready()
        robots.drain()
        event_id = rig.goal(100, 1)  # 5 s: killed well before its end
        rig.kill()
        robots.wait_for(lambda e: e.get("event") == "end" and e.get("ns") == "rejoin_b", timeout=30)
        assert not any(e["payload"]["terminal"] for e in feedback(rig.app.events, event_id))

        rig.again()
        end = rig.ends(event_id)[0]
        assert (end["state"], end.get("result")) == ("finished", "succeeded"), end
        assert end["output"] == {"sequence": sequence(40)}
    finally:
        rig.close()


def answers(events: list[Event], correlation: str) -> list[dict[str, Any]]:
    """The state or error events that answer the query or cancel `correlation` (a redelivery counted once)."""
    found = {
        e["id"]: e for _, e in events if e.get("type") in ("state", "error") and e.get("correlation") == correlation
    }
    return list(found.values())


def answered(correlation: str, events: list[Event]) -> bool:
    return bool(answers(events, correlation))


@pytest.mark.parametrize("robots", [("rejoin_d",)], indirect=True)
def test_a_goal_that_ended_before_a_kill_is_answered_with_its_end_by_the_restarted_node(
    fibo_run: tuple[Model, Path, Path], robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    """A query and a cancel of a goal that ended in the last run, by its id: its end, from the ledger (a new
    user's finding: they were refused `unsupported`, "no fibonacci goal G is known to this node")."""
    rig = Restarting(fibo_run, broker, tmp_path, "rejoin_d")
    try:
        rig.ready()
        event_id = rig.goal(5, 1)
        end = rig.ends(event_id)[0]
        assert (end["state"], end.get("result")) == ("finished", "succeeded"), end
        rig.kill()
        rig.again()
        for kind in ("query", "cancel"):
            correlation = f"{kind}-{uuid.uuid4().hex[:8]}"
            event = {
                "id": correlation,
                "time": now_rfc3339(),
                "correlation": correlation,
                "payload": {"goal": end["goal"]},
            }
            rig.app.send(f"{goal_topic(rig.robot)}/{kind}", event)
            (answer,) = answers(rig.app.wait(partial(answered, correlation), timeout=30), correlation)
            assert answer["type"] == "state", answer
            payload = answer["payload"]
            assert (payload["state"], payload["result"], payload["goal"]) == ("finished", "succeeded", end["goal"])
            assert payload["terminal"] is True and payload["message"] == end["message"], payload
    finally:
        rig.close()


def test_a_goal_whose_server_forgot_it_ends_failed_saying_so(
    fibo_run: tuple[Model, Path, Path], ros2_domain: int, broker: Mosquitto, tmp_path: Path
) -> None:
    robot = robot_process("rejoin_c")
    rig = Restarting(fibo_run, broker, tmp_path, "rejoin_c")
    try:
        rig.ready()
        event_id = rig.goal(LONG, 1)
        goal = feedback(rig.app.events, event_id)[0]["payload"]["goal"]
        rig.kill()
        robot.stop()  # the robot restarts: its new action server never had the goal
        robot = robot_process("rejoin_c")

        rig.again()
        end = rig.ends(event_id)[0]
        assert (end["state"], end["reason"]) == ("failed", "unreachable"), end
        words = end["message"]
        assert words.startswith(f"the edge node restarted while it followed this goal ({goal})"), words
        assert f"the action server does not know goal {goal}" in words, words
        assert words.endswith("its outcome is unknown"), words
    finally:
        rig.close()
        robot.stop()


SHARED = {"rejoin_s1": "rejoin_s1", "rejoin_s2": "rejoin_s2"}


def owners(app: AppClient) -> dict[str, tuple[str, int | None]]:
    """Each shared robot's last status: its state and the pid of the process that owns it."""
    out: dict[str, tuple[str, int | None]] = {}
    for t, e in list(app.events):
        parts = t.split("/")
        if len(parts) == 3 and parts[2] == "status" and parts[1] in SHARED:
            p = e["payload"]
            out[parts[1]] = (p["state"], (p.get("owner") or {}).get("pid"))
    return out


@pytest.mark.parametrize("robots", [tuple(SHARED.values())], indirect=True)
def test_a_goal_in_flight_is_followed_on_by_the_process_that_takes_the_robot_over(
    fibo_run: tuple[Model, Path, Path], robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    """Each process has a state directory of its own (as on two hosts): the new owner learns the goal's id and
    feedback numbering from the admitted entries on the broker (node/admitted.py)."""
    configs = [
        node_config(tmp_path / f"node{i}.yaml", broker, tmp_path / f"state{i}", SHARED, fleet="rejoin")
        for i in range(2)
    ]
    environ = env.child_env([])
    app = AppClient(broker.url, ["td2adaptor/+/status", *(f"td2adaptor/{r}/#" for r in SHARED)], client_id="share-app")
    runs = [RunProcess(run_args(fibo_run, config, "--share"), env=environ) for config in configs]
    try:
        for run in runs:
            run.wait_ready()
        pids = {run.proc.pid for run in runs}

        def shared_out() -> bool:
            online = [pid for state, pid in owners(app).values() if state == "online"]
            return len(online) == 2 and set(online) == pids

        assert until(shared_out, 60), owners(app)
        victim = next(run for run in runs if run.proc.pid == owners(app)["rejoin_s1"][1])
        survivor = next(run for run in runs if run is not victim)
        goals_answered(app, "rejoin_s1")
        event_id = start_goal(app, "rejoin_s1")
        app.wait(lambda ev: running(ev, event_id), timeout=30)
        killed = time.monotonic()
        victim.proc.kill()
        victim.proc.wait(10)
        before = len({e["id"] for e in feedback(app.events, event_id)})
        assert until(lambda: len({e["id"] for e in feedback(app.events, event_id)}) > before, 60)
        print(f"kill -9 -> the goal's feedback relayed again by the new owner: {time.monotonic() - killed:.2f} s")

        app.wait(terminal("feedback", event_id), timeout=60)
        assert owners(app)["rejoin_s1"] == ("online", survivor.proc.pid)
        check_followed_on(feedback(app.events, event_id), before, LONG)
        assert "following fibonacci goal" in survivor.output(), survivor.output()[-3000:]
        assert "took the robot over" in survivor.output(), survivor.output()[-3000:]
    finally:
        for run in runs:
            run.close()
        app.close()


HANDED = {"ended_s1": "ended_s1", "ended_s2": "ended_s2"}


@pytest.mark.parametrize("robots", [tuple(HANDED.values())], indirect=True)
def test_a_goal_that_ended_before_its_owner_died_is_answered_with_its_end_by_the_process_that_took_over(
    fibo_run: tuple[Model, Path, Path], robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    """Each process with a state directory of its own (as on two hosts): the new owner's ledger learnt the ended
    goal from the admitted entries on the broker (node/admitted.py `seed`), and answers a query of it by its id."""
    configs = [
        node_config(tmp_path / f"node{i}.yaml", broker, tmp_path / f"state{i}", HANDED, fleet="ended") for i in range(2)
    ]
    environ = env.child_env([])
    app = AppClient(broker.url, ["td2adaptor/+/status", *(f"td2adaptor/{r}/#" for r in HANDED)], client_id="ended-app")
    runs = [RunProcess(run_args(fibo_run, config, "--share"), env=environ) for config in configs]

    def owner(robot: str) -> tuple[str, int | None]:
        found = [e["payload"] for t, e in list(app.events) if t == f"td2adaptor/{robot}/status"]
        return (found[-1]["state"], (found[-1].get("owner") or {}).get("pid")) if found else ("", None)

    try:
        for run in runs:
            run.wait_ready()
        pids = {run.proc.pid for run in runs}
        assert until(lambda: {owner(r) for r in HANDED} == {("online", pid) for pid in pids}, 60), app.events[-4:]
        victim = next(run for run in runs if run.proc.pid == owner("ended_s1")[1])
        survivor = next(run for run in runs if run is not victim)
        goals_answered(app, "ended_s1")
        event_id = start_goal(app, "ended_s1", 5)
        app.wait(terminal("feedback", event_id), timeout=60)
        end = next(e["payload"] for e in feedback(app.events, event_id) if e["payload"]["terminal"])
        assert (end["state"], end.get("result")) == ("finished", "succeeded"), end
        victim.proc.kill()
        victim.proc.wait(10)
        assert until(lambda: owner("ended_s1") == ("online", survivor.proc.pid), 60), owner("ended_s1")
        correlation = f"query-{uuid.uuid4().hex[:8]}"
        event = {"id": correlation, "time": now_rfc3339(), "correlation": correlation, "payload": {"goal": end["goal"]}}
        app.send(f"{goal_topic('ended_s1')}/query", event)
        (answer,) = answers(app.wait(partial(answered, correlation), timeout=30), correlation)
        assert answer["type"] == "state", answer
        payload = answer["payload"]
        assert (payload["state"], payload["result"], payload["goal"]) == ("finished", "succeeded", end["goal"])
    finally:
        for run in runs:
            run.close()
        app.close()
