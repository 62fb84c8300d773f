"""The CLI through click's runner and as a real subprocess: exit codes, formats, stdin, writing files."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli, main
from td2adaptor.model.exposed import BROKER_LOGIN
from tests.conftest import EXAMPLE, REPO

IFACE = ["-I", str(EXAMPLE / "interfaces")]
TD = str(EXAMPLE / "td.json")


@pytest.fixture
def runner() -> CliRunner:
    return CliRunner()


def test_version_and_help(runner: CliRunner) -> None:
    from td2adaptor import __version__

    result = runner.invoke(cli, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"td2adaptor {__version__}"
    for command in ([], ["validate"], ["types"], ["instantiate"], ["migrate"]):
        result = runner.invoke(cli, [*command, "--help"])
        assert result.exit_code == 0 and "Usage:" in result.output, command


def test_validate_valid_td(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["validate", TD, *IFACE])
    assert result.exit_code == 0, result.output
    assert "valid (0 errors, 0 warnings)" in result.output


def test_validate_json_format(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["validate", str(EXAMPLE / "td.reference-dialect.json"), *IFACE, "--format", "json"])
    assert result.exit_code == 0
    doc = json.loads(result.stdout)
    assert doc["valid"] is True and doc["warnings"] > 5
    first = doc["diagnostics"][0]
    assert set(first) == {"code", "severity", "message", "hint", "pointer", "file", "line", "col"}


def test_invalid_input_exit_1_with_located_errors(runner: CliRunner, tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(
        '{"title": "x",\n  "actions": {"a": {"forms": '
        '[{"href": "ros:a", "rosv:name": "/a//b", "rosv:type": "x/srv/Y"}]}}}'
    )
    result = runner.invoke(cli, ["validate", str(bad), "--format", "json"])
    assert result.exit_code == 1
    doc = json.loads(result.stdout)
    codes = {d["code"] for d in doc["diagnostics"]}
    assert {"ROS410", "ROS423"} <= codes
    assert all(d["file"] == str(bad) for d in doc["diagnostics"])


def test_syntax_error_exit_1(runner: CliRunner, tmp_path: Path) -> None:
    bad = tmp_path / "broken.json"
    bad.write_text('{"title": \n  }')
    result = runner.invoke(cli, ["validate", str(bad)])
    assert result.exit_code == 1 and f"{bad}:2:3: error TD004" in result.output


def test_usage_error_exit_2(runner: CliRunner) -> None:
    assert runner.invoke(cli, ["validate"]).exit_code == 2
    assert runner.invoke(cli, ["validate", TD, "--format", "yaml"]).exit_code == 2
    assert runner.invoke(cli, ["no-such-command"]).exit_code == 2


def test_stdin(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["validate", "-", *IFACE], input=Path(TD).read_bytes())
    assert result.exit_code == 0, result.output
    assert "<stdin>: valid" in result.output


def test_strict(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["validate", str(EXAMPLE / "td.reference-dialect.json"), *IFACE, "--strict"])
    assert result.exit_code == 1


def test_types_table_and_json(runner: CliRunner) -> None:
    result = runner.invoke(cli, ["types", TD, *IFACE])
    assert result.exit_code == 0
    lines = result.stdout.splitlines()
    assert lines[0] == "package robotnik_rb_1_adaptor" and lines[1] == "GoToComponent"
    assert any("gotoRun" in line and "robot_local_control_msgs/srv/GoToPetition" in line for line in lines)
    result = runner.invoke(cli, ["types", TD, *IFACE, "--format", "json"])
    rows = json.loads(result.stdout)["types"]["endpoints"]
    assert [r["name"] for r in rows][:3] == ["gotoRun", "gotoCancel", "gotoQuery"]
    assert all(r["ros1"] and r["ros2"] for r in rows)


def test_instantiate_writes_td(runner: CliRunner, tmp_path: Path) -> None:
    out = tmp_path / "rb1_a.td.json"
    result = runner.invoke(
        cli, ["instantiate", str(EXAMPLE / "rb1.tm.json"), "-o", str(out), "--set", "robotName=rb1_base_a"]
    )
    assert result.exit_code == 0, result.output
    td = json.loads(out.read_text())
    assert td["@type"] == "Thing"
    assert td["actions"]["gotoRun"]["forms"][0]["rosv:name"].startswith("/rb1_base_a/")
    assert runner.invoke(cli, ["validate", str(out), *IFACE]).exit_code == 0


def test_instantiate_missing_placeholder_writes_nothing(runner: CliRunner, tmp_path: Path) -> None:
    tm = tmp_path / "m.tm.json"
    tm.write_text(
        json.dumps(
            {
                "@context": ["https://www.w3.org/2022/wot/td/v1.1"],
                "@type": "tm:ThingModel",
                "title": "{{A}} and {{B}}",
                "properties": {"p": {"type": "number", "maximum": "{{MAX}}"}},
            }
        )
    )
    out = tmp_path / "out.json"
    out.write_text("precious")
    result = runner.invoke(cli, ["instantiate", str(tm), "-o", str(out), "--format", "json"])
    assert result.exit_code == 1
    missing = [d for d in json.loads(result.stdout)["diagnostics"] if d["code"] == "TM301"]
    assert len(missing) == 1 and all(n in missing[0]["message"] for n in ("A", "B", "MAX"))
    assert out.read_text() == "precious"
    result = runner.invoke(
        cli, ["instantiate", str(tm), "-o", "-", "--set", "A=x", "--set", "B=y", "--set", "MAX=47.7"]
    )
    assert result.exit_code == 0
    td = json.loads(result.stdout[result.stdout.index("{") :])
    assert td["title"] == "x and y" and td["properties"]["p"]["maximum"] == 47.7


def test_migrate_command(runner: CliRunner, tmp_path: Path) -> None:
    out = tmp_path / "migrated.json"
    legacy = REPO / "tests" / "data" / "legacy"
    result = runner.invoke(
        cli, ["migrate", str(legacy / "service.json"), str(legacy / "topic.json"), *IFACE, "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    td = json.loads(out.read_text())
    assert td["actions"]["gotoRun"]["rosv:procedure"] == {
        "query": "gotoQuery",
        "cancel": "gotoCancle",
        "missionId": "state/header/id",
    }
    assert runner.invoke(cli, ["validate", str(out), *IFACE, "--strict"]).exit_code == 0


def test_migrate_refuses_invalid_input(runner: CliRunner, tmp_path: Path) -> None:
    out = tmp_path / "never.json"
    result = runner.invoke(cli, ["migrate", str(tmp_path / "missing.json"), "-o", str(out)])
    assert result.exit_code == 1 and not out.exists()


def test_internal_error_is_one_line_exit_3(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import td2adaptor.compiler.pipeline

    def boom(*_a: object, **_k: object) -> None:
        raise RuntimeError("simulated bug")

    monkeypatch.setattr(td2adaptor.compiler.pipeline, "compile", boom)
    with pytest.raises(SystemExit) as exc:
        main(["validate", TD])
    assert exc.value.code == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error: RuntimeError: simulated bug" in err


def _run(*args: str, stdin: bytes | None = None) -> subprocess.CompletedProcess[bytes]:
    exe = Path(sys.executable).parent / "td2adaptor"
    return subprocess.run(
        [str(exe), *args], input=stdin, capture_output=True, timeout=60, env={**os.environ, "NO_COLOR": "1"}
    )


def test_subprocess_bad_inputs_never_trace(tmp_path: Path) -> None:
    cases = {
        "binary.json": b"\x00\xff\xfe garbage",
        "array.json": b"[1, 2, 3]",
        "deep.json": b"[" * 50_000 + b"]" * 50_000,
        "nan.json": b'{"title": NaN}',
        "dupe.json": b'{"title": "a", "title": "b"}',
        "empty.json": b"",
        "weird.json": json.dumps(
            {"title": 5, "actions": {"a": {"forms": [{"rosv:name": 7, "rosv:type": None}]}}}
        ).encode(),
    }
    for name, data in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        proc = _run("validate", str(path))
        assert proc.returncode == 1, (name, proc.stderr)
        assert b"Traceback" not in proc.stderr and b"internal error" not in proc.stderr, (name, proc.stderr)
        assert str(path).encode() in proc.stderr


def test_subprocess_stdin_and_colour_only_on_tty() -> None:
    proc = _run("validate", "-", *IFACE, stdin=Path(TD).read_bytes())
    assert proc.returncode == 0 and b"\x1b[" not in proc.stderr and b"<stdin>: valid" in proc.stderr


def test_a_name_too_long_for_a_file_is_refused_at_validate_and_nothing_is_written(
    runner: CliRunner, tmp_path: Path
) -> None:
    text = Path(TD).read_text(encoding="utf-8").replace('"GoToComponent"', '"' + "G" * 5000 + '"')
    td = tmp_path / "td.json"
    td.write_text(text, encoding="utf-8")
    result = runner.invoke(cli, ["validate", str(td), *IFACE, "--no-cache"])
    assert result.exit_code == 1 and "ROS430" in result.output and "5000 characters long" in result.output
    out = tmp_path / "out"
    result = runner.invoke(cli, ["gen", str(td), *IFACE, "--partial", "-o", str(out), "--no-cache"])
    assert result.exit_code == 1 and "internal error" not in result.output
    assert not out.exists()


def test_expose_output_follows_the_umask(runner: CliRunner, tmp_path: Path) -> None:
    """`-o FILE` gets the mode any file the user writes gets (it was 0600 whatever the umask), a file it
    replaces too, as generated trees do; the atomic write's temporary file is gone."""
    out = tmp_path / "r1.td.json"
    out.write_text("old", encoding="utf-8")
    out.chmod(0o600)
    for mask, mode in ((0o022, 0o644), (0o002, 0o664), (0o077, 0o600)):
        previous = os.umask(mask)
        try:
            result = runner.invoke(cli, ["expose", TD, *IFACE, "--robot", "r1", "--broker", "mqtt://h:1883", "-o",
                                         str(out)])  # fmt: skip
        finally:
            os.umask(previous)
        assert result.exit_code == 0, result.output
        assert json.loads(out.read_text(encoding="utf-8"))["@type"] == "Thing"
        assert stat.S_IMODE(out.stat().st_mode) == mode, oct(mask)
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_expose_writes_the_td_of_one_robot(runner: CliRunner, tmp_path: Path) -> None:
    """No placeholder left, the id names the robot, the hrefs the broker given; the Thing Model of the fleet
    (`{{robotName}}`, `{{mqttBroker}}`) works as well as the TD; bad robot ids and broker URLs are refused."""
    out = tmp_path / "rb1_a.td.json"
    args = ["--robot", "rb1_a", "--broker", "mqtt://10.0.0.5:1884"]
    result = runner.invoke(cli, ["expose", TD, *IFACE, *args, "-o", str(out)])
    assert result.exit_code == 0, result.output
    text = out.read_text(encoding="utf-8")
    td = json.loads(text)
    assert "{{" not in text and td["@type"] == "Thing" and td["id"] == "urn:dev:wot:robotnik:rb1:rb1_a"
    hrefs = {f["href"] for s in ("properties", "actions", "events") for a in td[s].values() for f in a["forms"]}
    assert all(h.startswith("mqtt://10.0.0.5:1884/td2adaptor/rb1_a/") for h in hrefs)
    other = runner.invoke(cli, ["expose", str(EXAMPLE / "rb1.tm.json"), *IFACE, "--robot", "rb1_b", *args[2:]])
    assert other.exit_code == 0, other.output
    assert json.loads(other.output)["id"] != td["id"] and "{{" not in other.output
    validated = runner.invoke(cli, ["validate", str(out)])
    assert validated.exit_code == 0, validated.output
    # the robot's ROS version decides the message layouts: time as ROS 1 (secs/nsecs) or ROS 2 names it
    ros1 = runner.invoke(cli, ["expose", TD, *IFACE, *args, "--ros", "1"])
    assert ros1.exit_code == 0, ros1.output
    assert '"nsecs"' in ros1.output and '"nanosec"' not in ros1.output and '"nanosec"' in text
    # a fleet on its own topic root (run's topic_root): every topic under it, and nothing left at the default
    rooted = runner.invoke(cli, ["expose", TD, *IFACE, *args, "--topic-root", "site1/robots"])
    assert rooted.exit_code == 0, rooted.output
    forms = [f for s in ("properties", "actions", "events") for a in json.loads(rooted.output)[s].values()
             for f in a["forms"]]  # fmt: skip
    assert all(f["href"].startswith("mqtt://10.0.0.5:1884/site1/robots/rb1_a/") for f in forms)
    assert all((f.get("mqv:topic") or f["mqv:filter"]).startswith("site1/robots/rb1_a/") for f in forms)
    # property events at QoS 0 (run's property_qos): the observe forms say so
    qos0 = runner.invoke(cli, ["expose", TD, *IFACE, *args, "--property-qos", "0"])
    assert qos0.exit_code == 0, qos0.output
    properties = json.loads(qos0.output)["properties"]
    presence = properties.pop("presence")  # the robot's status: always QoS 1
    observe = [f for p in properties.values() for f in p["forms"] if "mqv:filter" in f]
    assert observe and {f["mqv:qos"] for f in observe} == {"0"}
    assert presence["forms"][0]["mqv:qos"] == "1"
    # a broker that wants a password (run with TD2ADAPTOR_MQTT_USERNAME): the nosec TD says basic (issue 30)
    assert td["security"] == ["nosec_sc"]
    basic = runner.invoke(cli, ["expose", TD, *IFACE, *args, "--basic"])
    assert basic.exit_code == 0, basic.output
    assert json.loads(basic.output)["securityDefinitions"] == {"basic_sc": BROKER_LOGIN}
    assert json.loads(basic.output)["security"] == ["basic_sc"]
    bad_roots = (["--topic-root", "a/#"], ["--topic-root", "/abs"], ["--topic-root", ""])
    for bad in (["--robot", "all"], ["--robot", "{{robotName}}"], ["--broker", "mqtt://u:p@h:1"], ["--broker", "x"],
                *bad_roots):  # fmt: skip
        refused = runner.invoke(cli, ["expose", TD, *IFACE, *args, *bad])
        assert refused.exit_code == 1 and "td2adaptor expose:" in refused.output, (bad, refused.output)
    refused = runner.invoke(cli, ["expose", TD, *IFACE, *args, "--property-qos", "2"])
    assert refused.exit_code == 2 and "'2' is not one of '0', '1'" in refused.output, refused.output


def test_a_robot_td_made_from_a_thing_model_links_it_and_does_not_repeat_its_description(
    runner: CliRunner, tmp_path: Path
) -> None:
    """TD 1.1: an instance links its model (`rel: type`, application/tm+json); the model's description says how
    to instantiate it, which is no robot's description. The fleet's exposed Thing Model keeps it."""
    model = tmp_path / "rb1.tm.json"
    model.write_bytes((EXAMPLE / "rb1.tm.json").read_bytes())
    said = json.loads(model.read_text(encoding="utf-8"))["description"]
    assert "instantiate it per robot" in said
    out = tmp_path / "rb1_a.td.json"
    result = runner.invoke(cli, ["expose", str(model), *IFACE, "--robot", "rb1_a", "--broker", "mqtt://h:1883", "-o",
                                 str(out)])  # fmt: skip
    assert result.exit_code == 0, result.output
    td = json.loads(out.read_text(encoding="utf-8"))
    assert td["links"] == [{"rel": "type", "href": "rb1.tm.json", "type": "application/tm+json"}]
    assert "instantiate" not in td["description"] and td["description"].startswith("Robotnik RB-1 (rb1_a)")
    # the link is the model's real place: validate reads it and checks the robot offers what it makes mandatory
    validated = runner.invoke(cli, ["validate", str(out)])
    assert validated.exit_code == 0 and "TM35" not in validated.output, validated.output
    del td["actions"]["gotoRun"]
    out.write_text(json.dumps(td), encoding="utf-8")
    broken = runner.invoke(cli, ["validate", str(out)])
    assert broken.exit_code == 1 and "TM352" in broken.output and "gotoRun" in broken.output, broken.output
    # a TD that is no instance of a model links none, and keeps its own description
    plain = json.loads(runner.invoke(cli, ["expose", TD, *IFACE, "--robot", "rb1_a", "--broker", "mqtt://h:1"]).output)
    assert "links" not in plain and plain["description"].startswith(json.loads(Path(TD).read_text())["description"])
    # the fleet's Thing Model (gen -b events) is the model: its description stays
    from td2adaptor import compile as compile_td
    from td2adaptor.model.exposed import exposed_td

    compiled = compile_td(model, interfaces=[EXAMPLE / "interfaces"])
    assert compiled.model is not None
    fleet = exposed_td(compiled.model)
    assert fleet["description"].startswith(said) and "links" not in fleet


def test_types_lists_ros_actions_and_components_of_actions_only(runner: CliRunner) -> None:
    """nav_base: NavigationComponent and DockingComponent have nothing but ROS actions."""
    nav = REPO / "examples" / "nav_base"
    args = ["types", str(nav / "td.json"), "-I", str(nav / "interfaces"), "--no-cache"]
    result = runner.invoke(cli, args)
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[1] == "NavigationComponent" and lines[2].split()[:3] == ["navigateToPose", "action", "client"]
    assert "DockingComponent" in lines
    docking = [line.split() for line in lines[lines.index("DockingComponent") + 1 :][:2]]
    assert [(row[0], row[1], row[4], row[5], row[6]) for row in docking] == [
        ("dockRobot", "action", "nav_base_msgs/action/DockRobot", "ros1:yes", "ros2:yes"),
        ("undockRobot", "action", "nav_base_msgs/action/UndockRobot", "ros1:yes", "ros2:yes"),
    ]
    result = runner.invoke(cli, [*args, "--format", "json"])
    doc = json.loads(result.stdout)["types"]
    rows = {r["name"]: r for r in doc["endpoints"]}
    assert rows["navigateToPose"] == {
        "component": "NavigationComponent",
        "name": "navigateToPose",
        "kind": "action",
        "role": "client",
        "ros_name": "/{{robotName}}/navigate_to_pose",
        "type": "nav_base_msgs/action/NavigateToPose",
        "ros1": True,
        "ros2": True,
    }
    assert doc["actions"]["ros2"] == [
        "nav_base_msgs/action/NavigateToPose",
        "nav_base_msgs/action/DockRobot",
        "nav_base_msgs/action/UndockRobot",
    ]
