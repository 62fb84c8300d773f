"""Where the engine starts a ROS action goal (runtime/engine/goals.py): on its loop when the port can start it
without waiting (`QuickGoalStart`: one thread hand-off fewer between the invoke event and the goal request),
on the robot's lane of the call pool when it cannot. Simulated action servers (`SimActions`) on the in-process
bus; each goal still gets its feedback in order and one terminal event, also when the loop's mission timeout
ends it while the server's thread publishes its feedback."""

from __future__ import annotations

import json
import threading
from collections.abc import Mapping
from typing import Any

import pytest

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.ros.port import GoalListener
from td2adaptor.runtime.ros.simport import SimActions, SimPort
from tests.runtime.edge import Recorder
from tests.runtime.rb1 import sim
from tests.runtime.threads_proc import action_model

ROBOT = "fibo_start"
TOPIC = f"td2adaptor/{ROBOT}/MathComponent/fibonacci"


class Watched(SimPort):
    """The simulated port, noting the thread each goal is started on; `quick` False: it can never start one
    without waiting (as the ROS 1 bridge, or a ROS 2 component whose calls are all in flight)."""

    quick = True

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.started_on: list[str] = []

    def start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str:
        self.started_on.append(threading.current_thread().name)
        return super().start_goal(component, action, payload, timeout, listener)

    def try_start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str | None:
        if not self.quick:
            return None
        return super().try_start_goal(component, action, payload, timeout, listener)


def run_goals(quick: bool, count: int = 3) -> tuple[list[str], list[list[dict[str, Any]]]]:
    """`count` goals one after the other: the threads they were started on, and each one's feedback events."""
    broker = LocalBroker()
    port = Watched(action_model(), sim(robot_id=ROBOT), readers={}, writers={}, actions=SimActions(step=0.01))
    port.quick = quick
    engine = serve(action_model(), port, RuntimeConfig(robot=ROBOT, bus="local", state_dir=""), broker=broker)
    app = Recorder(broker, [f"{TOPIC}/feedback"], "goal-start-app")
    try:
        feedback = []
        for i in range(count):
            app.send(TOPIC, json.dumps({"correlation": f"g{i}", "payload": {"order": 4}}).encode())
            events = app.wait(
                lambda es, c=f"g{i}": any(e["correlation"] == c and e["payload"]["terminal"] for _, e in es)
            )  # type: ignore[misc]
            feedback.append([e["payload"] for _, e in events if e["correlation"] == f"g{i}"])
        return port.started_on, feedback
    finally:
        app.close()
        engine.stop()


@pytest.mark.parametrize("quick", [True, False])
def test_a_goal_is_started_on_the_loop_when_the_port_can_and_on_the_call_pool_otherwise(quick: bool) -> None:
    started_on, feedback = run_goals(quick)
    if quick:
        assert started_on == ["td2adaptor-engine"] * 3
    else:
        assert len(started_on) == 3 and all(name.startswith("td2adaptor-call-") for name in started_on), started_on
    for payloads in feedback:  # either way: accepted, each feedback message in order, one end
        assert [p["seq"] for p in payloads] == list(range(1, len(payloads) + 1))
        assert [p["state"] for p in payloads] == ["queued"] + ["running"] * (len(payloads) - 2) + ["finished"]
        assert [p["feedback"]["sequence"] for p in payloads[1:-1]] == [[0, 1, 1, 2, 3, 5][: k + 2] for k in range(4)]


def test_a_goal_given_up_while_its_feedback_streams_in_gets_no_event_after_its_terminal_one() -> None:
    """The mission timeout (the loop's timer) ends goals whose feedback the simulated server sends every
    millisecond from its own thread, which publishes it there: each goal's events are numbered without a gap
    and its terminal event (failed, timeout) is its last one, whichever thread came first (the goal's lock)."""
    broker = LocalBroker()
    port = Watched(action_model(), sim(robot_id=ROBOT), readers={}, writers={}, actions=SimActions(step=0.001))
    config = RuntimeConfig(robot=ROBOT, bus="local", state_dir="", mission_timeout=0.5)
    engine = serve(action_model(), port, config, broker=broker)
    app = Recorder(broker, [f"{TOPIC}/feedback"], "goal-timeout-app")
    streamed = 0
    try:
        # five goals given up, then a short one: an event of theirs published late would be in before its end
        for i, order in enumerate([100000] * 5 + [1]):
            app.send(TOPIC, json.dumps({"correlation": f"t{i}", "payload": {"order": order}}).encode())
            app.wait(
                lambda es, c=f"t{i}": any(e["correlation"] == c and e["payload"]["terminal"] for _, e in es),
                timeout=10,
            )  # type: ignore[misc]
        events = [e for _, e in app.wait(lambda es: True)]
        for i in range(5):
            payloads = [e["payload"] for e in events if e["correlation"] == f"t{i}"]
            assert [p["seq"] for p in payloads] == list(range(1, len(payloads) + 1))
            assert [p["terminal"] for p in payloads] == [False] * (len(payloads) - 1) + [True]
            assert (payloads[-1]["state"], payloads[-1]["reason"]) == ("failed", "timeout")
            streamed += len(payloads) > 3  # feedback came before the timeout
        # on a loaded machine a goal's 0.5 s may pass before its server thread runs: the race needs only some
        assert streamed >= 2, streamed
    finally:
        app.close()
        engine.stop()
