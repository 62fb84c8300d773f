"""The pure parts of goals and procedures: ROS goal status words → procedure states, mapped state fields, a
goal's end crossing the ROS 1 bridge as JSON, and the `goal_feedback_grace` and `action_server_timeout` settings
reaching the generated package's goal.
(The real middleware tests are test_edge_node_actions_* and test_edge_node_mapped_procedure.)"""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from td2adaptor.model import Procedure
from td2adaptor.model.events import GOAL_WORDS, STATES
from td2adaptor.runtime.config import ConfigError, RuntimeConfig, load_config
from td2adaptor.runtime.engine.goals import _running_word, goal_status
from td2adaptor.runtime.node.roslink import make_port
from td2adaptor.runtime.ros.bridge import Ros1Bridge
from td2adaptor.runtime.ros.genport import CALLS_PER_COMPONENT, FEEDBACK_GRACE, Layout
from td2adaptor.runtime.ros.port import (
    GOAL_STATES,
    GoalEnd,
    PortCallFailed,
    PortRejected,
    PortUnavailable,
    QuickGoalStart,
)
from td2adaptor.runtime.ros.procedures import read
from tests.runtime.edge import GoalEvents

MAPPED = Procedure(
    "taskRun",
    "taskQuery",
    "taskCancel",
    ("int64_value",),
    ("uint8_value",),
    (("0", "queued"), ("1", "running"), ("2", "finished"), ("3", "failed"), ("4", "cancelled")),
    ("string_value",),
    frozenset({"run", "query"}),
)


@pytest.mark.parametrize(
    ("word", "done", "state", "reason"),
    [
        ("pending", False, "queued", None),
        ("accepted", False, "queued", None),
        ("executing", False, "running", None),
        ("canceling", False, "running", None),
        ("succeeded", True, "finished", None),
        ("canceled", True, "cancelled", None),
        ("aborted", True, "failed", "aborted"),
        ("rejected", True, "failed", "rejected"),
        ("lost", True, "failed", "unreachable"),
        ("executing", True, "failed", "robot-error"),  # ended, but not in an end state: never reported finished
    ],
)
def test_goal_words(word: str, done: bool, state: str, reason: str | None) -> None:
    status = goal_status(word, done, "the server's words" if done else "")
    assert (status.state, status.reason, status.terminal) == (state, reason, done)
    assert status.result in GOAL_WORDS and status.state in STATES
    if done and word != "executing":
        assert status.message == "the server's words"


@pytest.mark.parametrize("word", GOAL_STATES)
def test_a_running_feedback_event_never_carries_an_end_word(word: str) -> None:
    # feedback trailing the result (or held by feedback_period) is still sent as `running`: with a running word
    running = _running_word(word)
    assert goal_status(running, False).state == "running"
    assert running == (word if word in ("executing", "canceling") else "executing")


def test_every_goal_state_is_a_word_of_the_contract() -> None:
    assert set(GOAL_STATES) <= set(GOAL_WORDS)


def test_a_goal_end_crosses_the_bridge_as_json() -> None:
    end = GoalEnd("aborted", {"sequence": [0]}, "13 is unlucky")
    assert GoalEnd.from_json(json.loads(json.dumps(end.to_json()))) == end
    lost = GoalEnd.from_json(json.loads(json.dumps(GoalEnd("lost", None, "gone", PortUnavailable("gone")).to_json())))
    assert (lost.status, lost.message, type(lost.error), str(lost.error)) == ("lost", "gone", PortUnavailable, "gone")
    refused = GoalEnd.from_json(json.loads(json.dumps(GoalEnd("rejected", error=PortRejected("no")).to_json())))
    assert isinstance(refused.error, PortRejected) and refused.error.reason == "rejected"


def test_mapped_state_field() -> None:
    answer = {"int64_value": 42, "uint8_value": 1, "string_value": "working"}
    reading = read(answer, MAPPED, "query")
    assert reading.status is not None and reading.unmapped is None
    assert (reading.status.state, reading.status.message, reading.status.mission_id) == ("running", "working", 42)
    failed = read({**answer, "uint8_value": 3}, MAPPED, "query").status
    assert failed is not None and (failed.state, failed.reason, failed.terminal) == ("failed", "robot-error", True)
    # a value the mapping does not name: no state, and the value to log
    assert read({**answer, "uint8_value": 9}, MAPPED, "query") == type(reading)(None, unmapped="9")
    # a response kind that carries no state (here: cancel): the call was taken, nothing more
    assert read(answer, MAPPED, "cancel").status is None


def test_convention_is_the_default() -> None:
    rb1 = Procedure("gotoRun", "gotoQuery", None, ("state", "header", "id"), stateful=frozenset({"run", "query"}))
    answer = {"state": {"current_state": "finished", "last_event": "cancel", "header": {"id": 7}}}
    status = read(answer, rb1, "query").status
    assert status is not None and (status.state, status.mission_id) == ("cancelled", 7)


def test_boolean_state_fields_read_as_true_and_false() -> None:
    states = (("true", "finished"), ("false", "running"))
    proc = Procedure("run", "query", None, (), ("done",), states, (), frozenset({"query"}))
    status = read({"done": True}, proc, "query").status
    assert status is not None and status.state == "finished"


class _Handle:
    """What GeneratedPort reads of a generated GoalHandle: its id; a ROS 2 one also has a `server_timeout`."""

    goal_id = "0123456789abcdef0123456789abcdef"

    def __init__(self, grace: float | None) -> None:
        self.grace = grace


class _Watched(_Handle):
    server_timeout = 99.0


class _Component:
    """The generated component class's surface GeneratedPort uses for a ROS action (`start_<action>`)."""

    handle: type[_Handle] = _Handle

    def __init__(self, *args: Any, timeout: float, wait_timeout: float) -> None:
        pass

    def register(self) -> None:
        pass

    def construct_count_Goal(self, **fields: Any) -> dict[str, Any]:
        return fields

    def start_count(self, goal: Any, *, feedback_grace: float | None = None, **callbacks: Any) -> _Handle:
        return self.handle(feedback_grace)


class _WatchedComponent(_Component):
    handle = _Watched


def _started(config: RuntimeConfig, distro: str, component: type[_Component] = _Component) -> _Handle:
    """The handle of a goal sent through the port the edge node makes for `config`."""
    package = ModuleType("fake_adaptor")
    package.CountComponent = component  # type: ignore[attr-defined]
    port = make_port(Layout(("CountComponent",)), package, config, distro, node=object() if distro == "ros2" else None)
    try:
        goal = port.start_goal("CountComponent", "count", {"order": 3}, 1.0, GoalEvents())
        follower = port._follower("CountComponent", "count", goal)
        assert follower is not None
        handle: _Handle = follower.handle
        return handle
    finally:
        port.close()


def _grace(config: RuntimeConfig, distro: str) -> float | None:
    """The feedback grace a goal sent through the port the edge node makes for `config` is started with."""
    return _started(config, distro).grace


def test_goal_feedback_grace_reaches_the_generated_goal(tmp_path: Path) -> None:
    # default: the ROS version's own
    assert _grace(RuntimeConfig(robot="r"), "ros2") == FEEDBACK_GRACE["ros2"] == 0.01
    assert _grace(RuntimeConfig(robot="r"), "ros1") == FEEDBACK_GRACE["ros1"] == 0.1
    # the YAML key and the environment variable (which wins), for both ROS versions
    path = tmp_path / "robot.yaml"
    path.write_text("robot: r\ngoal_feedback_grace: 0\n")
    assert load_config(path, env={}).goal_feedback_grace == 0.0
    assert _grace(load_config(path, env={}), "ros2") == 0.0
    assert _grace(load_config(path, env={}), "ros1") == 0.0
    configured = load_config(path, env={"TD2ADAPTOR_GOAL_FEEDBACK_GRACE": "0.002"})
    assert _grace(configured, "ros2") == 0.002
    # the ROS 1 bridge tells its child, per robot (None: the child's ROS 1 default)
    bridge = Ros1Bridge(
        Layout(("CountComponent",)),
        "pkg",
        [("r", "r"), ("s", "s")],
        python="python3",
        feedback_grace={"r": 0.002, "s": None},
    )
    assert bridge.init_request()["feedback_grace"] == {"r": 0.002, "s": None}
    for bad in ("-0.1", "2"):
        with pytest.raises(ConfigError, match="goal_feedback_grace"):
            load_config(path, env={"TD2ADAPTOR_GOAL_FEEDBACK_GRACE": bad})


def _server_timeout(config: RuntimeConfig) -> float:
    """The server_timeout of a goal's handle sent through the port the edge node makes for `config` (ROS 2)."""
    handle = _started(config, "ros2", _WatchedComponent)
    assert isinstance(handle, _Watched)
    return handle.server_timeout


def test_action_server_timeout_reaches_the_goal_handle(tmp_path: Path) -> None:
    assert _server_timeout(RuntimeConfig(robot="r")) == RuntimeConfig(robot="r").action_server_timeout == 2.5
    path = tmp_path / "robot.yaml"
    path.write_text("robot: r\naction_server_timeout: 0\n")
    assert _server_timeout(load_config(path, env={})) == 0.0
    assert _server_timeout(load_config(path, env={"TD2ADAPTOR_ACTION_SERVER_TIMEOUT": "1.5"})) == 1.5
    # a ROS 1 handle has none (ROS 1 tells at once): the port leaves it alone
    assert not hasattr(
        _started(load_config(path, env={"TD2ADAPTOR_ACTION_SERVER_TIMEOUT": "1.5"}), "ros1"), "server_timeout"
    )
    for bad in ("-1", "nan", "inf", "x"):
        with pytest.raises(ConfigError, match="action_server_timeout"):
            load_config(path, env={"TD2ADAPTOR_ACTION_SERVER_TIMEOUT": bad})


def test_a_ros2_goal_starts_without_waiting_only_while_a_call_of_its_component_is_free() -> None:
    """`try_start_goal` (QuickGoalStart, so the engine may start the goal on its loop) sends the goal when one of
    the component's CALLS_PER_COMPONENT is free at once, else says None and sends nothing; on ROS 1 always None
    (the bridge's child starts goals on its own threads)."""
    package = ModuleType("fake_adaptor")
    package.CountComponent = _Component  # type: ignore[attr-defined]
    config = RuntimeConfig(robot="r")
    port = make_port(Layout(("CountComponent",)), package, config, "ros2", node=object())
    try:
        assert isinstance(port, QuickGoalStart)
        goal = port.try_start_goal("CountComponent", "count", {"order": 3}, 1.0, GoalEvents())
        assert goal == _Handle.goal_id and port._follower("CountComponent", "count", goal) is not None
        taken = port._locks["CountComponent"]
        for _ in range(CALLS_PER_COMPONENT):  # every call of the component is in flight (waiting for the robot)
            assert taken.acquire(blocking=False)
        before = dict(port._goals)
        assert port.try_start_goal("CountComponent", "count", {"order": 3}, 1.0, GoalEvents()) is None
        assert port._goals == before  # nothing sent
        taken.release()
        assert port.try_start_goal("CountComponent", "count", {"order": 3}, 1.0, GoalEvents()) == _Handle.goal_id
        with pytest.raises(PortCallFailed):  # a payload the goal message does not take: at once, as start_goal
            port.try_start_goal("CountComponent", "nothing", {"order": 3}, 1.0, GoalEvents())
    finally:
        port.close()
    ros1 = make_port(Layout(("CountComponent",)), package, config, "ros1", node=None)
    try:
        assert ros1.try_start_goal("CountComponent", "count", {"order": 3}, 1.0, GoalEvents()) is None
    finally:
        ros1.close()
