"""The edge node killed mid-mission and started again (issue 30, item 6), for real: `td2adaptor run` in a
process of its own serving the simulated RB-1 (ROS 2 Jazzy, its own process) over a real mosquitto; the node is
killed with SIGKILL while the robot runs the mission, and started again on the same state directory. The
mission's terminal event comes exactly once, from the restarted node, which follows the mission on by its
mission id; an invoke sent again under its id is answered, while the mission runs and after its end.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.ros2 import env
from tests.ros2.common import EXAMPLE, PACKAGE, Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, Event
from tests.runtime.edge import RunProcess, check_mission, feedback
from tests.runtime.rb1 import GOAL, check_outbound, terminal

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

ROBOT = "restart_1"
NAMESPACE = "edge_restart"
#: how long the simulated robot's mission runs: longer than killing the node and starting it again takes
DURATION = 12.0
GOTO = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"


@pytest.fixture
def robot(rb1_prefix: Path) -> Iterator[Process]:
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", str(DURATION)]
    process = Process([*args, "--namespace", NAMESPACE], env.child_env([rb1_prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        yield process
    finally:
        process.stop()


def _states(events: list[Event]) -> list[str]:
    return [e["payload"]["state"] for e in feedback(events, "go-1")]


def test_a_node_killed_mid_mission_and_restarted_ends_it_once_and_answers_a_resent_invoke(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robot: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    config = tmp_path / "node.yaml"
    settings = [f"bus: {broker.url}", f"robot: {ROBOT}", f"namespace: {NAMESPACE}", "poll_period: 0.1"]
    settings += ["property_period: 0", "call_timeout: 5", f"state_dir: {tmp_path / 'state'}"]
    config.write_text("\n".join(settings) + "\n", encoding="utf-8")
    args = [str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--config", str(config), "--package", PACKAGE]
    environ = env.child_env([rb1_prefix, adaptor_build[1]])
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"], client_id="restart-app")
    node = RunProcess(args, env=environ)
    again: RunProcess | None = None
    invoke: dict[str, Any] = {"id": "go-1", "correlation": "go-1", "source": "test", "payload": GOAL}
    try:
        node.wait_ready()
        app.send(GOTO, invoke)
        app.wait(lambda ev: "running" in _states(ev), timeout=30)
        node.proc.send_signal(signal.SIGKILL)
        node.proc.wait(10)
        assert not any(e["payload"]["terminal"] for e in feedback(app.events, "go-1"))

        again = RunProcess(args, env=environ)
        again.wait_ready()
        seen = len(feedback(app.events, "go-1"))
        app.send(GOTO, invoke)  # sent again while the robot runs it: answered with its state
        app.wait(lambda ev: len(feedback(ev, "go-1")) > seen, timeout=30)
        answer = feedback(app.events, "go-1")[seen]
        assert answer in feedback(app.events, "go-1")[:seen] or answer["payload"]["terminal"], answer
        app.wait(terminal("feedback", "go-1"), timeout=DURATION + 30)
        events = check_mission(app.events, "go-1", ["queued", "running", "finished"])
        assert "following gotoRun mission" in again.output(), again.output()[-2000:]

        # after its end: the terminal event again, the same event (no second mission)
        count = len(feedback(app.events, "go-1"))
        app.send(GOTO, invoke)
        app.wait(lambda ev: len(feedback(ev, "go-1")) > count, timeout=30)
        assert feedback(app.events, "go-1")[-1] == events[-1]
        terminals = {e["id"] for e in feedback(app.events, "go-1") if e["payload"]["terminal"]}
        assert len(terminals) == 1
    finally:
        if again is not None:
            again.close()
        node.close()
        app.close()
    check_outbound(app.events)
