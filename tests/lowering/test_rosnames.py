"""ROS graph names, namespace placeholders, identifiers and package names."""

from __future__ import annotations

import pytest

from td2adaptor.lowering.rosnames import (
    identifier_problem,
    name_problems,
    package_name,
    package_name_problem,
    split_namespace,
)
from td2adaptor.model import RosName


@pytest.mark.parametrize(
    ("raw", "path", "namespaced"),
    [
        ("/#robotName/robot_local_control/state", "robot_local_control/state", True),
        ("/{{robotName}}/ar_pose_marker", "ar_pose_marker", True),
        ("{{robotName}}/odom", "odom", True),
        ("/door1/door_controller/command", "/door1/door_controller/command", False),
    ],
)
def test_split_namespace(raw: str, path: str, namespaced: bool) -> None:
    name, _ = split_namespace(raw)
    assert name == RosName(path, namespaced)
    assert name_problems(name) == []


def test_resolve_with_and_without_namespace() -> None:
    name = RosName("robot_local_control/state", True)
    assert name.resolve("rb1_base_a") == "/rb1_base_a/robot_local_control/state"
    assert name.resolve("/rb1_base_b/") == "/rb1_base_b/robot_local_control/state"
    assert name.resolve("") == "/robot_local_control/state"
    assert RosName("/door1/cmd").resolve("rb1_base_a") == "/door1/cmd"
    assert name.binding_form() == "/{{robotName}}/robot_local_control/state"


@pytest.mark.parametrize(
    ("raw", "fragment"),
    [
        ("/a//b", "ROS 1"),
        ("/1abc", "ROS 1"),
        ("/abc/", "end with '/'"),
        ("/a__b", "'__'"),
        ("/x/{{robotName}}/y", "placeholder"),
        ("/has space", "ROS 1"),
        ("", "empty"),
        ("/door1/cmd\n", "ROS 1"),
    ],
)
def test_invalid_names(raw: str, fragment: str) -> None:
    name, _ = split_namespace(raw)
    problems = name_problems(name)
    assert problems and any(fragment in p for p in problems), problems


def test_identifiers() -> None:
    assert identifier_problem("GoToComponent") is None
    assert identifier_problem("class") is not None  # Python and C++
    assert identifier_problem("namespace") is not None  # C++ only
    assert identifier_problem("9lives") is not None
    assert identifier_problem("bad-name") is not None
    assert identifier_problem("a__b") is not None
    assert identifier_problem("name\n") is not None  # `$` would match before a trailing newline


def test_package_names() -> None:
    assert package_name("Robotnik RB-1") == "robotnik_rb_1_adaptor"
    assert package_name("  42 Weird -- Title!! ") == "weird_title_adaptor"
    assert package_name("door_adaptor") == "door_adaptor"
    assert package_name("") == "thing_adaptor"
    assert package_name_problem("robotnik_rb_1_adaptor") is None
    assert package_name_problem("Bad-Name") is not None
    assert package_name_problem("a__b") is not None


def test_names_that_become_file_names_are_bounded() -> None:
    from td2adaptor.lowering.rosnames import MAX_NAME, identifier_problem, package_name, package_name_problem

    assert identifier_problem("A" * MAX_NAME) is None
    assert "characters long" in (identifier_problem("A" * 5000) or "")
    assert "characters long" in (package_name_problem("a" * (MAX_NAME + 1)) or "")
    derived = package_name("Robot " * 1000)
    assert len(derived) <= MAX_NAME and derived.endswith("_adaptor") and package_name_problem(derived) is None
    assert package_name("Robotnik RB-1") == "robotnik_rb_1_adaptor"
    assert package_name("my_adaptor") == "my_adaptor"
