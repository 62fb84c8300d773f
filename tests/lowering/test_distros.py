"""A type only one ROS version can use makes the TD valid for that version: Nav2's NavigateToPose as published
(its feedback uses builtin_interfaces/Duration, which ROS 1 does not define) is a ROS 2 action, the ROS 1
backends are skipped or refuse it with the reason; the reverse for a message using ROS 1's std_msgs/Duration.
An interface folder's problems both versions find are reported as before (tests/golden/diagnostics/bad_interface).
"""

from __future__ import annotations

import json
import py_compile
from pathlib import Path
from typing import Any

from click.testing import CliRunner

import td2adaptor
from td2adaptor.cli.main import cli
from td2adaptor.diagnostics import Severity
from td2adaptor.model import ActionDef

DATA = Path(__file__).resolve().parents[1] / "data"
NAV2 = DATA / "nav2"  # nav2_msgs/action/NavigateToPose.action as Nav2 publishes it
ROS1_ONLY = DATA / "ros1only"  # legacy_msgs/msg/Uptime: a std_msgs/Duration field
NAV2_ACTION = "nav2_msgs/action/NavigateToPose"
CONTEXT = ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"]


def _td(title: str, actions: dict[str, Any] | None = None, properties: dict[str, Any] | None = None) -> dict[str, Any]:
    return {
        "@context": CONTEXT,
        "@type": "Thing",
        "title": title,
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "actions": actions or {},
        "properties": properties or {},
    }


def nav2_td() -> dict[str, Any]:
    """A base whose navigation is Nav2's own NavigateToPose action."""
    return _td(
        "Nav2 Base",
        actions={
            "navigateToPose": {
                "rosv:component": "NavigationComponent",
                "input": {
                    "type": "object",
                    "properties": {"pose": {"type": "object"}, "behavior_tree": {"type": "string"}},
                },
                "output": {
                    "type": "object",
                    "properties": {"error_code": {"type": "integer"}, "error_msg": {"type": "string"}},
                },
                "forms": [
                    {
                        "href": "ros:navigate_to_pose",
                        "op": "invokeaction",
                        "rosv:name": "/{{robotName}}/navigate_to_pose",
                        "rosv:type": NAV2_ACTION,
                        "rosv:interface": "action",
                    }
                ],
            }
        },
    )


def topic_td(title: str, type_name: str, name: str = "uptime") -> dict[str, Any]:
    return _td(
        title,
        properties={
            name: {
                "rosv:component": "StatusComponent",
                "observable": True,
                "readOnly": True,
                "type": "object",
                "forms": [
                    {
                        "href": f"ros:{name}",
                        "op": ["readproperty", "observeproperty"],
                        "rosv:name": f"/{{{{robotName}}}}/{name}",
                        "rosv:type": type_name,
                    }
                ],
            }
        },
    )


def _write(tmp_path: Path, td: dict[str, Any]) -> Path:
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td, indent=2), encoding="utf-8")
    return path


def _cli(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, [*args, "--no-cache"])
    return result.exit_code, result.output


def test_nav2_navigate_to_pose_is_a_valid_ros2_action(tmp_path: Path) -> None:
    result = td2adaptor.compile(_write(tmp_path, nav2_td()), interfaces=[NAV2])
    assert result.model is not None, [(d.code, d.message) for d in result.diagnostics]
    assert not [d for d in result.diagnostics if d.code.startswith("TY")]  # no TY520 for ROS 1's missing Duration
    (warning,) = [d for d in result.diagnostics if d.code.startswith("ROS42")]
    assert warning.code == "ROS424" and warning.severity is Severity.WARNING
    assert warning.pointer == "/actions/navigateToPose/forms/0/rosv:type"
    assert f"type '{NAV2_ACTION}' is for ROS 2 only: field 'navigation_time' of {NAV2_ACTION}_Feedback is a " in (
        warning.message
    )
    assert "builtin_interfaces/msg/Duration, which ROS 1 does not define" in warning.message
    assert "the rospy and mROS backends cannot use it" in warning.message
    assert "`duration`" in (warning.hint or "")  # how to write a file both versions build
    action = result.model.ros2.action(NAV2_ACTION)
    assert isinstance(action, ActionDef)
    assert [f.type.base for f in action.feedback.fields][1:3] == ["builtin_interfaces/msg/Duration"] * 2
    assert result.model.ros1.get(NAV2_ACTION) is None and result.model.ros1.actions == ()
    assert "builtin_interfaces/msg/Duration" in (result.model.ros1.why_unavailable(NAV2_ACTION) or "")


def test_gen_makes_the_ros2_adaptors_and_names_the_skipped_ros1_backends(tmp_path: Path) -> None:
    td, out = _write(tmp_path, nav2_td()), tmp_path / "out"
    code, text = _cli("validate", str(td), "-I", str(NAV2))
    assert code == 0 and "valid (0 errors" in text, text
    code, text = _cli("gen", str(td), "-I", str(NAV2), "-o", str(out))
    assert code == 0, text
    assert sorted(p.name for p in out.iterdir()) == ["events", "rclpy"]
    skipped = [line for line in text.splitlines() if "GEN807" in line]
    assert len(skipped) == 2, text
    rospy, mros = skipped
    assert "rospy backend skipped" in rospy and f"its type {NAV2_ACTION} is for ROS 2 only" in rospy
    assert "builtin_interfaces/msg/Duration, which ROS 1 does not define" in rospy
    assert "mros backend skipped" in mros and "mROS has no actions" in mros
    for source in (out / "rclpy").rglob("*.py"):
        py_compile.compile(str(source), cfile=str(tmp_path / "pyc"), doraise=True)
    package_xml = next((out / "rclpy").rglob("package.xml")).read_text(encoding="utf-8")
    assert "<exec_depend>nav2_msgs</exec_depend>" in package_xml


def test_a_ros1_backend_named_with_b_fails_with_the_reason(tmp_path: Path) -> None:
    td, out = _write(tmp_path, nav2_td()), tmp_path / "out"
    code, text = _cli("gen", str(td), "-I", str(NAV2), "-o", str(out), "-b", "rospy")
    assert code == 1 and not out.exists()
    (error,) = [line for line in text.splitlines() if " error " in line]
    assert "GEN842: rospy backend: action 'navigateToPose' cannot be generated: its type " in error
    assert "builtin_interfaces/msg/Duration, which ROS 1 does not define" in error
    assert error.endswith("at /actions/navigateToPose")


def test_a_ros1_only_message_is_the_reverse(tmp_path: Path) -> None:
    td, out = _write(tmp_path, topic_td("Old Base", "legacy_msgs/msg/Uptime")), tmp_path / "out"
    result = td2adaptor.compile(td, interfaces=[ROS1_ONLY])
    assert result.model is not None
    (warning,) = [d for d in result.diagnostics if d.code == "ROS424"]
    assert "is for ROS 1 only: field 'uptime' of legacy_msgs/msg/Uptime is a std_msgs/msg/Duration, which ROS 2" in (
        warning.message
    )
    assert "the rclpy backend cannot use it" in warning.message
    code, text = _cli("gen", str(td), "-I", str(ROS1_ONLY), "-o", str(out))
    assert code == 0, text
    assert {"events", "rospy"} <= {p.name for p in out.iterdir()} and not (out / "rclpy").exists()
    assert "rclpy backend skipped" in text and "is for ROS 1 only" in text
    code, text = _cli("gen", str(td), "-I", str(ROS1_ONLY), "-o", str(tmp_path / "other"), "-b", "rclpy")
    assert code == 1 and "GEN820" in text and "std_msgs/msg/Duration, which ROS 2 does not define" in text


def test_a_file_only_ros2_can_read_says_what_ros1_found(tmp_path: Path) -> None:
    """A ROS 2 bounded string is an error for ROS 1's parser alone: the type is for ROS 2, with that reason."""
    folder = tmp_path / "interfaces" / "mix_msgs" / "msg"
    folder.mkdir(parents=True)
    (folder / "Label.msg").write_text("string<=10 name\n", encoding="utf-8")
    result = td2adaptor.compile(
        _write(tmp_path, topic_td("Labeller", "mix_msgs/msg/Label", "label")), interfaces=[tmp_path / "interfaces"]
    )
    assert result.model is not None
    assert not [d for d in result.diagnostics if d.severity is Severity.ERROR]
    (warning,) = [d for d in result.diagnostics if d.code == "ROS424"]
    assert "is for ROS 2 only: ROS 1 cannot read its definition: bounded types are a ROS 2 feature" in warning.message
    assert "Label.msg:1:1" in warning.message


def test_a_type_neither_version_can_use_is_an_error(tmp_path: Path) -> None:
    folder = tmp_path / "interfaces" / "mix_msgs" / "msg"
    folder.mkdir(parents=True)
    (folder / "Both.msg").write_text("builtin_interfaces/Duration a\nstd_msgs/Duration b\n", encoding="utf-8")
    result = td2adaptor.compile(
        _write(tmp_path, topic_td("Mixed", "mix_msgs/msg/Both", "both")), interfaces=[tmp_path / "interfaces"]
    )
    assert result.model is None
    (error,) = [d for d in result.diagnostics if d.severity is Severity.ERROR]
    assert error.code == "ROS424" and "can be used with neither ROS version" in error.message
    assert "ROS 1: field 'a'" in error.message and "ROS 2: field 'b'" in error.message


def test_a_problem_both_versions_find_is_reported_once_as_before(tmp_path: Path) -> None:
    folder = tmp_path / "interfaces" / "mix_msgs" / "msg"
    folder.mkdir(parents=True)
    (folder / "Gone.msg").write_text("nonexistent_msgs/Foo a\n", encoding="utf-8")
    result = td2adaptor.compile(
        _write(tmp_path, topic_td("Gone", "mix_msgs/msg/Gone", "gone")), interfaces=[tmp_path / "interfaces"]
    )
    assert result.model is None
    assert [(d.code, d.severity) for d in result.diagnostics if d.code.startswith(("TY", "ROS42"))] == [
        ("TY520", Severity.ERROR)
    ]
