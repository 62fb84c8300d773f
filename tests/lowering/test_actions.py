"""TD actions bound to ROS actions (`"rosv:interface": "action"`): type resolution (interface folders and the
ROS 1 typestore), lowering, the refusal of hidden action types, the one backend that cannot generate them (mros:
MROS907, skipped with --partial) and the goal events the events backend gives them. The rclpy and rospy action
clients are tested on real middleware in tests/backends/rclpy/test_rclpy_actions.py and
tests/backends/rospy/test_rospy_actions.py."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.backends.registry import load as load_backend
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import ActionEndpoint, Model
from td2adaptor.rostypes.registry import TypeRegistry

INTERFACES = Path(__file__).resolve().parents[1] / "data" / "actions"


def action_td(**extra: Any) -> dict[str, Any]:
    """A TD with one action bound to test_msgs/action/Fibonacci and one property."""
    td: dict[str, Any] = {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": "Fibo Bot",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "actions": {
            "fibonacci": {
                "rosv:component": "MathComponent",
                "input": {"type": "object", "properties": {"order": {"type": "integer"}}},
                "output": {
                    "type": "object",
                    "properties": {"sequence": {"type": "array", "items": {"type": "integer"}}},
                },
                "forms": [
                    {
                        "href": "ros:fibonacci",
                        "op": "invokeaction",
                        "rosv:name": "/{{robotName}}/fibonacci",
                        "rosv:type": "test_msgs/action/Fibonacci",
                        "rosv:interface": "action",
                    }
                ],
            }
        },
        "properties": {
            "chatter": {
                "rosv:component": "MathComponent",
                "observable": True,
                "readOnly": True,
                "forms": [
                    {
                        "href": "ros:chatter",
                        "op": ["readproperty", "observeproperty"],
                        "rosv:name": "/{{robotName}}/chatter",
                        "rosv:type": "std_msgs/msg/String",
                    }
                ],
            }
        },
    }
    td.update(extra)
    return td


def compile_td(tmp_path: Path, td: dict[str, Any]) -> td2adaptor.compiler.pipeline.Result:  # type: ignore[name-defined]
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    return td2adaptor.compile(path, interfaces=[INTERFACES])


def codes(result: Any, severity: Severity | None = None) -> list[str]:
    return [d.code for d in result.diagnostics if severity is None or d.severity is severity]


def test_action_types_resolve_from_interface_folders() -> None:
    for distro in ("ros1", "ros2"):
        reg = TypeRegistry(distro, [INTERFACES])  # type: ignore[arg-type]
        table = reg.table(["test_msgs/action/Fibonacci"])
        assert not table.missing
        adef = table.action("test_msgs/action/Fibonacci")
        assert [f.name for f in adef.goal.fields] == ["order"]
        assert [f.name for f in adef.result.fields] == ["sequence"]
        assert [f.name for f in adef.feedback.fields] == ["sequence"]
        assert table.message("test_msgs/action/Fibonacci_Goal") is adef.goal


def test_action_lowers_to_an_action_endpoint(tmp_path: Path) -> None:
    result = compile_td(tmp_path, action_td())
    assert result.model is not None, [d.message for d in result.diagnostics]
    assert "ROS425" not in codes(result)
    comp = result.model.component("MathComponent")
    assert comp.services == ()
    (action,) = comp.actions
    assert isinstance(action, ActionEndpoint)
    assert action.name == "fibonacci"
    assert action.type_name == "test_msgs/action/Fibonacci"
    assert action.ros_name.namespaced and action.ros_name.path == "fibonacci"
    assert result.model.namespaced


def test_goal_and_result_are_cross_checked(tmp_path: Path) -> None:
    td = action_td()
    td["actions"]["fibonacci"]["input"] = {"type": "object", "properties": {"order": {"type": "string"}}}
    td["actions"]["fibonacci"]["output"] = {"type": "object", "properties": {"sequense": {"type": "array"}}}
    result = compile_td(tmp_path, td)
    found = [d for d in result.diagnostics if d.code.startswith("XC6")]
    pointers = {d.pointer for d in found}
    assert "/actions/fibonacci/input/properties/order/type" in pointers, [(d.code, d.pointer) for d in found]
    assert any(p.startswith("/actions/fibonacci/output") for p in pointers), [(d.code, d.pointer) for d in found]


def test_ros1_only_action_from_the_typestore_is_resolved_and_cross_checked(tmp_path: Path) -> None:
    """actionlib/TwoInts exists only as ROS 1 genaction messages in rosbags' Noetic typestore: it resolves for
    ROS 1 (goal a, b; result sum) and the TD's schemas are checked against those."""
    td = action_td(**{"rosv:masterURI": "http://localhost:11311"})
    action = td["actions"]["fibonacci"]
    action["forms"][0]["rosv:type"] = "actionlib/action/TwoInts"
    action["input"] = {"type": "object", "properties": {"a": {"type": "integer"}, "b": {"type": "string"}}}
    action["output"] = {"type": "object", "properties": {"sum": {"type": "integer"}}}
    result = compile_td(tmp_path, td)
    assert result.model is not None, [d.message for d in result.diagnostics]
    (adef,) = result.model.ros1.actions
    assert [f.name for f in adef.goal.fields] == ["a", "b"] and [f.name for f in adef.result.fields] == ["sum"]
    found = [(d.code, d.pointer) for d in result.diagnostics if d.code.startswith("XC6")]
    assert [p for _, p in found] == ["/actions/fibonacci/input/properties/b/type"], found
    assert "ROS424" in codes(result, Severity.WARNING)  # no such action for ROS 2


def test_unknown_action_type_is_reported(tmp_path: Path) -> None:
    td = action_td()
    td["actions"]["fibonacci"]["forms"][0]["rosv:type"] = "test_msgs/action/Fibonaci"
    result = compile_td(tmp_path, td)
    assert result.model is None
    (found,) = [d for d in result.diagnostics if d.code == "ROS423"]
    assert "a folder holding test_msgs/action/Fibonaci.action" in (found.hint or "")


def test_unknown_action_type_hint_names_the_installed_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An action type installed with its package (the ros2 extra's test_msgs wheel, a sourced prefix) but not
    given with --interfaces: the hint names the package folder to pass."""
    prefix = tmp_path / "prefix"
    action = prefix / "share" / "test_msgs" / "action" / "Fibonacci.action"
    action.parent.mkdir(parents=True)
    action.write_bytes((INTERFACES / "test_msgs" / "action" / "Fibonacci.action").read_bytes())
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    td = tmp_path / "td.json"
    td.write_text(json.dumps(action_td()), encoding="utf-8")
    result = td2adaptor.compile(td)
    assert result.model is None
    (found,) = [d for d in result.diagnostics if d.code == "ROS423"]
    assert f"{action} defines it: add --interfaces {prefix / 'share' / 'test_msgs'}" in (found.hint or "")
    assert td2adaptor.compile(td, interfaces=[prefix / "share" / "test_msgs"]).model is not None


def test_action_type_for_a_service_binding_is_refused(tmp_path: Path) -> None:
    td = action_td()
    del td["actions"]["fibonacci"]["forms"][0]["rosv:interface"]
    result = compile_td(tmp_path, td)
    assert result.model is None
    (found,) = [d for d in result.diagnostics if d.code == "ROS421"]
    assert found.severity is Severity.ERROR and found.pointer == "/actions/fibonacci/forms/0/rosv:type"
    assert found.hint == (
        'to bind a ROS action, add "rosv:interface": "action" to the form (the goal is the input, the result the '
        "output)"
    )


def test_a_service_type_for_an_action_binding_says_how_to_bind_a_service(tmp_path: Path) -> None:
    td = action_td()
    td["actions"]["fibonacci"]["forms"][0]["rosv:type"] = "std_srvs/srv/Trigger"
    result = compile_td(tmp_path, td)
    (found,) = [d for d in result.diagnostics if d.code == "ROS421"]
    assert found.hint == 'to bind a service, remove "rosv:interface": "action" from the form'


def test_ros1_robot_gets_no_action_warning(tmp_path: Path) -> None:
    """The rospy backend generates actionlib clients: a ROS 1 robot's action is nothing to warn about."""
    result = compile_td(tmp_path, action_td(**{"rosv:masterURI": "http://localhost:11311"}))
    assert result.model is not None, [d.message for d in result.diagnostics]
    assert not codes(result, Severity.WARNING), [d.message for d in result.diagnostics]
    assert [a.name for a in result.model.ros1.actions] == ["test_msgs/action/Fibonacci"]


@pytest.mark.parametrize(
    ("written", "part"),
    [
        ("test_msgs/srv/Fibonacci_SendGoal", "SendGoal"),
        ("test_msgs/action/Fibonacci_GetResult", "GetResult"),
        ("test_msgs/msg/Fibonacci_FeedbackMessage", "FeedbackMessage"),
    ],
)
def test_hidden_action_types_point_at_the_action(tmp_path: Path, written: str, part: str) -> None:
    """Binding a ROS 2 action's hidden service or topic type is refused with the way out: bind the action."""
    td = action_td()
    form = td["actions"]["fibonacci"]["forms"][0]
    del form["rosv:interface"]
    form["rosv:type"] = written
    result = compile_td(tmp_path, td)
    assert result.model is None
    (found,) = [d for d in result.diagnostics if d.severity is Severity.ERROR]
    assert found.code == "ROS429" and found.pointer == "/actions/fibonacci/forms/0/rosv:type"
    assert f"the {part} type ROS 2 derives for action test_msgs/action/Fibonacci" in found.message
    assert '"rosv:interface": "action", "rosv:type": "test_msgs/action/Fibonacci"' in (found.hint or "")


def _model(tmp_path: Path) -> Model:
    result = compile_td(tmp_path, action_td())
    assert result.model is not None
    return result.model


@pytest.mark.parametrize(("backend", "code"), [("mros", "MROS907")])
def test_backends_without_actions_refuse_or_skip(tmp_path: Path, backend: str, code: str) -> None:
    model = _model(tmp_path)
    diags = Diagnostics()
    load_backend(backend).generate(model, GenOptions(), diags)
    errors = [d for d in diags if d.severity is Severity.ERROR]
    assert [d.code for d in errors] == [code], [d.message for d in diags]
    assert "fibonacci" in errors[0].message and errors[0].pointer == "/actions/fibonacci"
    assert "rospy backend" in (errors[0].hint or "")  # mROS is ROS 1: the ROS 1 backend with actions

    diags = Diagnostics()
    tree = load_backend(backend).generate(model, GenOptions(partial=True), diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    assert code in [d.code for d in diags if d.severity is Severity.WARNING]
    assert tree.files  # the property is still generated
    text = b"".join(tree.files.values()).decode("utf-8")
    assert "chatter" in text


def test_events_backend_gives_ros_actions_goal_events(tmp_path: Path) -> None:
    """A ROS action is a procedure by nature: invoke (the goal), feedback (ROS feedback, then the result),
    query and cancel under the action's topic, state; no warning."""
    from td2adaptor.model.events import Kind, build_catalog

    model = _model(tmp_path)
    diags = Diagnostics()
    tree = load_backend("events").generate(model, GenOptions(), diags)
    assert list(diags) == []
    specs = [s for s in build_catalog(model).specs if s.affordance == "fibonacci"]
    topics = {s.kind: s.topic("r1") for s in specs}
    assert topics == {
        Kind.INVOKE: "td2adaptor/r1/MathComponent/fibonacci",
        Kind.FEEDBACK: "td2adaptor/r1/MathComponent/fibonacci/feedback",
        Kind.QUERY: "td2adaptor/r1/MathComponent/fibonacci/query",
        Kind.CANCEL: "td2adaptor/r1/MathComponent/fibonacci/cancel",
        Kind.STATE: "td2adaptor/r1/MathComponent/fibonacci/state",
    }
    feedback = next(s for s in specs if s.kind is Kind.FEEDBACK).schema["properties"]["payload"]["properties"]
    assert feedback["feedback"]["properties"]["sequence"]["type"] == "array"  # test_msgs Fibonacci.Feedback
    assert feedback["output"]["properties"]["sequence"]["items"]["type"] == "integer"  # the TD's output
    exposed = json.loads(tree.files[f"{model.package_name}/td.mqtt.json"])
    assert {"fibonacci", "fibonacciQuery", "fibonacciCancel"} <= set(exposed["actions"])


def test_a_procedure_on_a_ros_action_is_refused(tmp_path: Path) -> None:
    """rosv:procedure links services into a procedure; on an action bound to a ROS action it would be ignored
    (it used to be, silently): ROS449 at the rosv:procedure member."""
    td = action_td()
    td["actions"]["fibonacci"]["rosv:procedure"] = {"query": "fibonacciQuery"}
    result = compile_td(tmp_path, td)
    assert result.model is None
    (found,) = [d for d in result.diagnostics if d.severity is Severity.ERROR]
    assert found.code == "ROS449" and found.pointer == "/actions/fibonacci/rosv:procedure"
    assert "action 'fibonacci' is bound to a ROS action" in found.message
    assert "remove rosv:procedure" in (found.hint or "")


def test_a_service_procedure_linking_a_ros_action_says_so(tmp_path: Path) -> None:
    td = action_td()
    td["actions"]["reset"] = {
        "rosv:component": "MathComponent",
        "rosv:procedure": {"cancel": "fibonacci"},
        "forms": [
            {
                "href": "ros:reset",
                "op": "invokeaction",
                "rosv:name": "/{{robotName}}/reset",
                "rosv:type": "std_srvs/srv/Trigger",
            }
        ],
    }
    result = compile_td(tmp_path, td)
    found = [d for d in result.diagnostics if d.code == "ROS442"]
    assert [d.message for d in found] == [
        "action 'reset': procedure cancel 'fibonacci' is bound to a ROS action, not a service"
    ]
