"""The RB-1 ROS 2 simulation's command line: one process serves one robot, several, or a fleet (`--count`)."""

from __future__ import annotations

import pytest

from examples.robotnik_rb1.sim.ros2 import namespaces, parse_args


def test_default_is_one_robot() -> None:
    assert namespaces(parse_args([])) == ["rb1_base_a"]


def test_repeated_namespaces() -> None:
    assert namespaces(parse_args(["--namespace", "a", "--namespace", "b"])) == ["a", "b"]


def test_count_makes_a_fleet_with_the_default_prefix() -> None:
    names = namespaces(parse_args(["--count", "100"]))
    assert names[0] == "rb1_base_0" and names[-1] == "rb1_base_99" and len(set(names)) == 100


def test_count_takes_the_namespace_as_prefix() -> None:
    assert namespaces(parse_args(["--namespace", "fleet", "--count", "3"])) == ["fleet_0", "fleet_1", "fleet_2"]


@pytest.mark.parametrize("argv", [["--count", "0"], ["--count", "2", "--namespace", "a", "--namespace", "b"]])
def test_count_refuses_what_it_cannot_name(argv: list[str]) -> None:
    with pytest.raises(SystemExit):
        namespaces(parse_args(argv))


def test_quiet_is_off_by_default() -> None:
    assert parse_args([]).quiet is False and parse_args(["--quiet"]).quiet is True


def test_executor_choice() -> None:
    assert parse_args([]).executor == "single" and parse_args(["--executor", "events"]).executor == "events"
    with pytest.raises(SystemExit):
        parse_args(["--executor", "threads"])
