"""Procedures the edge node can follow, and those it could not: validate says so before anything runs.

The std_srvs/Trigger case (issue 12): run/query/cancel on Trigger validated with 0 warnings, and at run time an
invoke was reported failed while the robot executed it. Now the query's response must carry a state: by the
procedures_msgs convention, or through a mapped field (`state`/`states`); test_msgs/srv/BasicTypes (an
integer mission id, a uint8 status, a string message) is the mapped example.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.diagnostics import Diagnostic, Severity
from td2adaptor.model import Model

INTERFACES = Path(__file__).resolve().parents[1] / "data" / "procedures"
STATES = {"0": "queued", "1": "running", "2": "finished", "3": "failed", "4": "cancelled"}
MAPPED = {"missionId": "int64_value", "state": "uint8_value", "states": STATES, "message": "string_value"}


def procedure_td(rtype: str, procedure: dict[str, Any], *, query: str | None = None) -> dict[str, Any]:
    """A TD with run/query/cancel actions of `rtype` (query: its own type), linked by `procedure`."""

    def action(name: str, type_name: str, link: dict[str, Any] | None = None) -> dict[str, Any]:
        out: dict[str, Any] = {
            "rosv:component": "TaskComponent",
            "forms": [
                {
                    "href": f"ros:task/{name}",
                    "op": "invokeaction",
                    "rosv:name": f"/{{{{robotName}}}}/task/{name}",
                    "rosv:type": type_name,
                }
            ],
        }
        if link is not None:
            out["rosv:procedure"] = link
        return out

    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": "Task Bot",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "actions": {
            "taskRun": action("run", rtype, {"query": "taskQuery", "cancel": "taskCancel", **procedure}),
            "taskQuery": action("query", query or rtype),
            "taskCancel": action("cancel", rtype),
        },
    }


def compile_td(tmp_path: Path, td: dict[str, Any]) -> tuple[Model | None, list[Diagnostic]]:
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    result = td2adaptor.compile(path, interfaces=[INTERFACES])
    return result.model, list(result.diagnostics)


def codes(diags: list[Diagnostic], severity: Severity) -> list[str]:
    return [d.code for d in diags if d.severity is severity]


def test_trigger_procedure_is_refused_at_validate_time(tmp_path: Path) -> None:
    model, diags = compile_td(tmp_path, procedure_td("std_srvs/srv/Trigger", {}))
    assert model is None
    (error,) = [d for d in diags if d.severity is Severity.ERROR]
    assert error.code == "ROS445" and error.pointer == "/actions/taskRun/rosv:procedure"
    assert "taskQuery" in error.message and "std_srvs/srv/Trigger" in error.message
    assert error.hint is not None and '"state"' in error.hint and '"states"' in error.hint


def test_trigger_procedure_through_the_cli(tmp_path: Path) -> None:
    """`td2adaptor validate` exits non-zero and prints the located diagnostic, no traceback."""
    from click.testing import CliRunner

    from td2adaptor.cli import cli

    path = tmp_path / "td.json"
    path.write_text(json.dumps(procedure_td("std_srvs/srv/Trigger", {})), encoding="utf-8")
    result = CliRunner().invoke(cli, ["validate", str(path), "--interfaces", str(INTERFACES)])
    assert result.exit_code != 0 and "ROS445" in result.output and "Traceback" not in result.output


def test_mapped_state_field(tmp_path: Path) -> None:
    model, diags = compile_td(tmp_path, procedure_td("test_msgs/srv/BasicTypes", MAPPED))
    assert model is not None, [d.message for d in diags]
    assert codes(diags, Severity.ERROR) == [] and codes(diags, Severity.WARNING) == []
    (proc,) = model.components[0].procedures
    assert proc.state == ("uint8_value",) and dict(proc.states) == STATES and proc.message == ("string_value",)
    assert proc.mission_id == ("int64_value",) and proc.stateful == frozenset({"run", "query", "cancel"})


def test_mapped_state_on_a_query_of_another_type(tmp_path: Path) -> None:
    """A run without a state (Trigger) is fine when the linked query has one: the run only starts it."""
    td = procedure_td(
        "std_srvs/srv/Trigger", {"state": "uint8_value", "states": STATES}, query="test_msgs/srv/BasicTypes"
    )
    model, diags = compile_td(tmp_path, td)
    assert model is not None, [d.message for d in diags]
    (proc,) = model.components[0].procedures
    assert proc.stateful == frozenset({"query"})
    # no mission id: a warning says the node asks about the robot's current mission
    assert codes(diags, Severity.WARNING) == ["ROS447"]


@pytest.mark.parametrize(
    ("procedure", "pointer", "words"),
    [
        ({"state": "uint8_value"}, "/state", "state without states"),
        ({"states": STATES}, "/states", "states without state"),
        ({"state": "uint8_value", "states": {"0": "done"}}, "/states/0", "'done', which is not a state"),
        ({"state": "uint8_value", "states": {"zero": "queued"}}, "/states/zero", "can never be read"),
        ({"state": "no_such_field", "states": STATES}, "", "has no field no_such_field"),
        ({"state": "uint8_value", "states": STATES, "message": "nope"}, "/message", "no field nope"),
    ],
)
def test_bad_mappings_are_located_errors(tmp_path: Path, procedure: dict[str, Any], pointer: str, words: str) -> None:
    model, diags = compile_td(tmp_path, procedure_td("test_msgs/srv/BasicTypes", procedure))
    errors = [d for d in diags if d.severity is Severity.ERROR]
    assert model is None and errors, [d.message for d in diags]
    assert any(words in d.message and d.pointer == "/actions/taskRun/rosv:procedure" + pointer for d in errors), [
        (d.code, d.message, d.pointer) for d in errors
    ]
    assert {d.code for d in errors} <= {"ROS445", "ROS446"}


def test_mission_id_that_cannot_travel_is_a_warning(tmp_path: Path) -> None:
    """The id is in the run response, but the query (Trigger) cannot be told which mission."""
    procedure = {"missionId": "int64_value", "state": "uint8_value", "states": STATES}
    td = procedure_td("test_msgs/srv/BasicTypes", procedure)
    td["actions"]["taskCancel"]["forms"][0]["rosv:type"] = "std_srvs/srv/Trigger"
    model, diags = compile_td(tmp_path, td)
    assert model is not None
    (warning,) = [d for d in diags if d.severity is Severity.WARNING]
    assert warning.code == "ROS447" and "taskCancel" in warning.message and warning.pointer == "/actions/taskCancel"


def test_procedure_without_a_query_is_a_warning(tmp_path: Path) -> None:
    """Run and cancel on Trigger, no query: the node can only say the robot took the run (ROS448), not its end."""
    td = procedure_td("std_srvs/srv/Trigger", {})
    del td["actions"]["taskQuery"]
    del td["actions"]["taskRun"]["rosv:procedure"]["query"]
    model, diags = compile_td(tmp_path, td)
    assert model is not None, [d.message for d in diags]
    (warning,) = [d for d in diags if d.code == "ROS448"]
    assert warning.severity is Severity.WARNING and warning.pointer == "/actions/taskRun/rosv:procedure"
    assert "taskRun" in warning.message and "has no query" in warning.message
    # a run response that carries a mapped state can be followed without a query: no ROS448
    procedure = {"state": "uint8_value", "states": STATES, "cancel": "taskCancel"}
    td = procedure_td("test_msgs/srv/BasicTypes", procedure)
    del td["actions"]["taskQuery"]
    del td["actions"]["taskRun"]["rosv:procedure"]["query"]
    model, diags = compile_td(tmp_path, td)
    assert model is not None and "ROS448" not in [d.code for d in diags], [d.message for d in diags]


@pytest.mark.parametrize("backend", ["rclpy", "rospy"])
def test_procedure_api_only_where_true(tmp_path: Path, backend: str) -> None:
    """`Started` and `mission_id=` exactly where the id can travel, in both Python backends alike."""
    import ast

    from td2adaptor.backends.registry import load as load_backend
    from td2adaptor.diagnostics import Diagnostics
    from td2adaptor.generation.backend import GenOptions

    def methods(td: dict[str, Any]) -> dict[str, ast.FunctionDef]:
        model, diags = compile_td(tmp_path, td)
        assert model is not None, [d.message for d in diags]
        tree = load_backend(backend).generate(model, GenOptions(), Diagnostics())
        (source,) = [data for rel, data in tree if rel.endswith("components.py")]
        return {n.name: n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.FunctionDef)}

    def params(fn: ast.FunctionDef) -> set[str]:
        return {a.arg for a in [*fn.args.args, *fn.args.kwonlyargs]}

    mapped = methods(procedure_td("test_msgs/srv/BasicTypes", MAPPED))
    assert "Started" in ast.unparse(mapped["call_taskRun"].returns or ast.Constant(None))
    assert "mission_id" in params(mapped["call_taskQuery"]) and "mission_id" in params(mapped["call_taskCancel"])

    no_id = procedure_td(
        "std_srvs/srv/Trigger", {"state": "uint8_value", "states": STATES}, query="test_msgs/srv/BasicTypes"
    )
    plain = methods(no_id)
    assert "Started" not in ast.unparse(plain["call_taskRun"].returns or ast.Constant(None))
    assert "mission_id" not in params(plain["call_taskQuery"]) and "mission_id" not in params(plain["call_taskCancel"])


def test_the_lowering_resolves_the_mission_slot_and_the_failure_rule_once(tmp_path: Path) -> None:
    """The request field that carries the mission id (per role) and how a response says the robot failed are in
    the model: the backends and the edge node read them there instead of each walking the types."""
    from td2adaptor.model import Failure

    model, diags = compile_td(tmp_path, procedure_td("test_msgs/srv/BasicTypes", MAPPED))
    assert model is not None, [d.message for d in diags]
    (proc,) = model.components[0].procedures
    assert proc.slot("query") == proc.slot("cancel") == ("int64_value",) and proc.slot("run") == ()
    assert {s.failure for s in model.components[0].services} == {Failure.NONE}  # BasicTypes says no failure

    td = procedure_td("test_msgs/srv/BasicTypes", {**MAPPED})
    td["actions"]["taskCancel"]["forms"][0]["rosv:type"] = "std_srvs/srv/Trigger"
    model, diags = compile_td(tmp_path, td)
    assert model is not None, [d.message for d in diags]
    (proc,) = model.components[0].procedures
    assert proc.slot("query") == ("int64_value",) and proc.slot("cancel") == ()  # and ROS447 said so
    assert model.components[0].service("taskCancel").failure is Failure.SUCCESS


@pytest.mark.parametrize(
    ("response", "failure"),
    [
        ("Outcome result", "RESULT"),
        ("Outcome[] result", "NONE"),
        ("bool success\nstring message", "SUCCESS"),
        ("bool success", "SUCCESS_ONLY"),
        ("bool success\nint32 message", "SUCCESS_ONLY"),
        ("bool[] success\nstring message", "NONE"),
        ("string result\nstring message", "NONE"),
    ],
)
def test_how_a_response_says_failure(tmp_path: Path, response: str, failure: str) -> None:
    from td2adaptor.model import Failure

    pkg = tmp_path / "ifaces" / "fail_msgs"
    (pkg / "srv").mkdir(parents=True)
    (pkg / "package.xml").write_text(
        '<?xml version="1.0"?><package format="3"><name>fail_msgs</name><version>0.0.0</version><description>x'
        '</description><maintainer email="a@b.c">a</maintainer><license>MIT</license>'
        "</package>",
        encoding="utf-8",
    )
    (pkg / "msg").mkdir()
    (pkg / "msg" / "Outcome.msg").write_text("string result\nstring message\n", encoding="utf-8")  # procedures_msgs'
    (pkg / "srv" / "Act.srv").write_text(f"int32 x\n---\n{response}\n", encoding="utf-8")
    td = procedure_td("fail_msgs/srv/Act", {})
    td["actions"] = {"act": td["actions"]["taskRun"]}
    del td["actions"]["act"]["rosv:procedure"]
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    result = td2adaptor.compile(path, interfaces=[tmp_path / "ifaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    assert result.model.components[0].service("act").failure is Failure[failure]
