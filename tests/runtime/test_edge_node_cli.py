"""`td2adaptor run` and `td2adaptor demo warehouse` refuse what cannot work with one clear line and exit 1
(usage errors: 2), before touching ROS or a broker where they can. The working paths are in
test_edge_node_ros2.py, test_edge_node_ros1.py and test_demo_warehouse.py.
"""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from tests.conftest import EXAMPLE

TD = str(EXAMPLE / "td.json")
IFACE = ["-I", str(EXAMPLE / "interfaces")]


def run(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.output


def one_line(output: str, prefix: str) -> str:
    lines = [line for line in output.splitlines() if line.startswith(prefix) and "warning:" not in line]
    assert len(lines) == 1, output
    return lines[0]


def test_run_help_names_every_option() -> None:
    code, out = run("run", "--help")
    assert code == 0
    for option in ("--robot", "--namespace", "--bus", "--config", "--ros", "--package", "--package-path", "--prefix"):
        assert option in out
    assert "--allow-insecure" in out and "--ros1-python" in out


def test_run_refuses_an_invalid_td(tmp_path: Path) -> None:
    bad = tmp_path / "td.json"
    bad.write_text('{"@context": "https://www.w3.org/2022/wot/td/v1.1", "title": 3}', encoding="utf-8")
    code, out = run("run", str(bad), "--robot", "r1")
    assert code == 1 and "invalid" in out


@pytest.mark.parametrize(
    ("yaml_text", "args", "message"),
    [
        ("poll_period: 0.5\n", [], "no robot id: give --robot"),
        ("robot: r1\ncolour: blue\n", [], "unknown key 'colour'"),
        ("robot: r1\npoll_period: soon\n", [], "poll_period: 'soon' is not a valid float"),
        ("robots:\n  - {robot: a}\n  - {robot: a}\n", [], "robot ids must be unique"),
        ("robots:\n  - {robot: a}\n  - {robot: b}\n", ["--robot", "c"], "has no robot 'c'"),
    ],
)
def test_run_configuration_errors(tmp_path: Path, yaml_text: str, args: list[str], message: str) -> None:
    config = tmp_path / "edge.yaml"
    config.write_text(yaml_text, encoding="utf-8")
    code, out = run("run", TD, *IFACE, "--config", str(config), *args)
    assert code == 1
    assert message in one_line(out, "td2adaptor run: configuration:")


@pytest.mark.parametrize(
    ("bus", "message"),
    [
        ("mqtt://192.0.2.10:1883", "not a loopback address (allow_insecure / --allow-insecure connects anyway)"),
        ("ftp://127.0.0.1", "use mqtt://host:port, mqtts://host:port or 'local'"),
        ("mqtt://user:secret@127.0.0.1:1883", "carries credentials"),
    ],
)
def test_run_checks_the_bus_against_the_td_security_before_connecting(bus: str, message: str) -> None:
    code, out = run("run", TD, *IFACE, "--robot", "r1", "--bus", bus, "--package", "no_such_adaptor")
    assert code == 1
    assert message in one_line(out, "td2adaptor run:")


def test_run_says_how_to_make_the_package_importable() -> None:
    code, out = run("run", TD, *IFACE, "--robot", "r1", "--package", "no_such_adaptor_pkg")
    assert code == 1
    line = one_line(out, "td2adaptor run:")
    assert "cannot import the adaptor package 'no_such_adaptor_pkg'" in line or "rclpy) is not importable" in line
    assert "--package-path" in line or "ros2 extra" in line


def test_run_ros1_with_a_missing_interpreter() -> None:
    code, out = run("run", TD, *IFACE, "--robot", "r1", "--ros", "1", "--ros1-python", "/nonexistent/python3")
    assert code == 1
    assert "cannot start the ROS 1 interpreter /nonexistent/python3" in one_line(out, "td2adaptor run:")


def test_run_usage_errors_exit_2() -> None:
    assert run("run", TD, "--ros", "3")[0] == 2
    assert run("run", TD, "--poll-period", "0")[0] == 2
    assert run("run")[0] == 2


def test_demo_refuses_what_cannot_work() -> None:
    code, out = run("demo", "warehouse", "--bus", "amqp://127.0.0.1")
    assert code == 1 and "use local or mqtt://host:port" in one_line(out, "td2adaptor demo warehouse:")
    assert run("demo", "warehouse", "--robots", "4")[0] == 2
    assert run("demo", "warehouse", "--duration", "-1")[0] == 2
    code, out = run("demo", "--help")
    assert code == 0 and "warehouse" in out


def test_run_counts_notes_alone_as_notes_not_as_more_of_nothing() -> None:
    """A Thing Model with notes only (infos): `run` printed "valid (0 errors, 0 warnings)", then "... and 3 more
    (ROS428 x1, ...)", more of nothing shown (a new user's lift)."""
    tm = str(EXAMPLE / "rb1.tm.json")
    code, out = run("run", tm, *IFACE, "--robot", "r1", "--bus", "nope://x")
    assert code == 1
    (summary,) = [line for line in out.splitlines() if "lists them" in line]
    assert summary.startswith("3 notes (") and "ROS428 x1" in summary, summary


def test_run_summarises_the_tds_warnings_instead_of_reprinting_them() -> None:
    dialect = str(EXAMPLE / "td.reference-dialect.json")
    given = [*IFACE, "--set", "robotName=r 1"]  # the input options run got, one with a space
    code, out = run("run", dialect, *given, "--robot", "r1", "--bus", "nope://x")
    assert code == 1 and "use mqtt://host:port" in out
    printed = [line for line in out.splitlines() if " warning " in line or " info " in line]
    assert len(printed) == 1, printed  # the first warning in full
    (summary,) = [line for line in out.splitlines() if line.startswith("... and ")]
    suggested = shlex.join(["td2adaptor", "validate", dialect, *given])
    assert "ROS412 x12" in summary and f"`{suggested}` lists them" in summary
    verdict = next(line for line in out.splitlines() if line.startswith(f"{dialect}: valid"))
    assert "(0 errors, 39 warnings)" in verdict  # counts every warning, not the one shown
    # the suggested command, run as printed, lists the same warnings (without -I it found 6 errors)
    code, out = run(*shlex.split(suggested)[1:])
    assert code == 0 and out.splitlines()[-1] == verdict
