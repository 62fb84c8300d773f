"""The front end end to end: every input kind of the RB-1 robot lowers into the same canonical model."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.compiler.pipeline import Result
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.frontend.migrate import migrate
from td2adaptor.model import (
    Durability,
    Model,
    Procedure,
    ProcedureRole,
    QoS,
    Role,
    RosName,
)
from tests import wot_corpus
from tests.conftest import EXAMPLE, REPO

INTERFACES = [EXAMPLE / "interfaces"]
LEGACY = [
    REPO / "tests" / "data" / "legacy" / "service.json",
    REPO / "tests" / "data" / "legacy" / "topic.json",
]


def compile_(src: Any, **kw: Any) -> Result:
    return td2adaptor.compile(src, interfaces=INTERFACES, **kw)


@pytest.fixture(scope="module")
def rb1() -> Model:
    result = compile_(EXAMPLE / "td.json")
    assert result.model is not None, [d.message for d in result.diagnostics]
    return result.model


def test_rb1_binding_td_is_clean(rb1: Model) -> None:
    result = compile_(EXAMPLE / "td.json")
    assert [d for d in result.diagnostics if d.severity is not Severity.INFO] == []
    assert rb1.package_name == "robotnik_rb_1_adaptor"
    assert [c.name for c in rb1.components] == [
        "GoToComponent",
        "PickComponent",
        "PlaceComponent",
        "AvailabilityComponent",
        "PoseMarkerComponent",
        "DoorComponent",
    ]


def test_rb1_services_procedures_and_topics(rb1: Model) -> None:
    goto = rb1.component("GoToComponent")
    assert [s.name for s in goto.services] == ["gotoRun", "gotoCancel", "gotoQuery"]
    every = frozenset({"run", "query", "cancel"})  # each response carries a procedures_msgs state
    assert goto.procedures == (
        Procedure(
            "gotoRun",
            "gotoQuery",
            "gotoCancel",
            ("state", "header", "id"),
            stateful=every,
            # where the mission id goes in the query's and the cancel's request (the lowering's one rule)
            slots=(("query", ("header", "id")), ("cancel", ("header", "id"))),
        ),
    )
    assert [s.procedure_role for s in goto.services] == [
        ProcedureRole.RUN,
        ProcedureRole.CANCEL,
        ProcedureRole.QUERY,
    ]
    run = goto.service("gotoRun")
    assert run.type_name == "robot_local_control_msgs/srv/GoToPetition"
    assert run.ros_name.resolve("rb1_base_a") == "/rb1_base_a/robot_local_control/NavigationComponent/GoToComponent/add"
    (status,) = rb1.component("AvailabilityComponent").subscribers
    assert status.type_name == "robot_local_control_msgs/msg/Status" and status.role is Role.SUBSCRIBER
    (door,) = rb1.component("DoorComponent").publishers
    assert door.ros_name == RosName("/door1/door_controller/command")
    assert door.qos == QoS(durability=Durability.TRANSIENT_LOCAL, depth=1, latch=True)


def test_rb1_types_resolve_for_both_distros(rb1: Model) -> None:
    for table in (rb1.ros1, rb1.ros2):
        assert table.complete
        assert table.service("procedures_msgs/srv/ProcedureQuery").request.fields[0].name == "header"
        assert table.message("robot_local_control_msgs/msg/Status").fields[0].name == "robot_id"
    ros1_header = [f.name for f in rb1.ros1.message("std_msgs/msg/Header").fields]
    ros2_header = [f.name for f in rb1.ros2.message("std_msgs/msg/Header").fields]
    assert ros1_header == ["seq", "stamp", "frame_id"] and ros2_header == ["stamp", "frame_id"]


def test_model_is_immutable(rb1: Model) -> None:
    with pytest.raises(AttributeError):
        rb1.package_name = "x"  # type: ignore[misc]
    schema = rb1.component("GoToComponent").service("gotoRun").input_schema
    with pytest.raises(TypeError):
        schema["type"] = "string"


def test_thing_model_lowers_to_the_same_components(rb1: Model) -> None:
    result = compile_(EXAMPLE / "rb1.tm.json")
    assert result.model is not None, [d.message for d in result.diagnostics if d.severity is Severity.ERROR]
    assert result.model.components == rb1.components
    assert result.model.ros1 == rb1.ros1 and result.model.ros2 == rb1.ros2
    # setting robotName bakes the namespace into the names
    baked = compile_(EXAMPLE / "rb1.tm.json", values={"robotName": "rb1_base_b"})
    assert baked.model is not None
    run = baked.model.component("GoToComponent").service("gotoRun")
    assert run.ros_name == RosName("/rb1_base_b/robot_local_control/NavigationComponent/GoToComponent/add")


def _shape(model: Model) -> list[Any]:
    """What code generation depends on: names, ROS names, types, roles, QoS, procedures."""
    return [
        (
            c.name,
            [(s.name, s.ros_name, s.type_name, s.procedure_role) for s in c.services],
            [(t.name, t.ros_name, t.type_name, t.role, t.qos) for t in c.topics],
            c.procedures,
        )
        for c in model.components
    ]


REFERENCE_DEFECTS = {
    "TD202": "ros",  # undeclared prefix
    "TD201": "lastModified",  # not a TD term
    "TD104": "created",  # epoch-string date
    "TD106": "http://www.w3.org/ns/td",  # pre-recommendation context
    "TD101": "href",  # link without href
    "ROS412": "empty href",
    "ROS415": "application/xml",
    "TD203": "level:",
    "XC603": "frame_id",
    "XC601": "title",
    "XC604": "header.id",
}


def test_reference_dialect_accepted_with_a_warning_per_defect(rb1: Model) -> None:
    result = compile_(EXAMPLE / "td.reference-dialect.json")
    assert result.model is not None, [d.message for d in result.diagnostics if d.severity is Severity.ERROR]
    warnings = [d for d in result.diagnostics if d.severity is Severity.WARNING]
    for code, fragment in REFERENCE_DEFECTS.items():
        assert any(d.code == code and fragment in d.message + d.pointer for d in warnings), (code, fragment)
    assert all(d.line is not None and d.file for d in warnings)
    assert any(d.code == "XC603" and "seq" in d.message for d in warnings)
    # equivalent to the binding TD for code generation
    assert _shape(result.model) == _shape(rb1)


def test_reference_dialect_in_input_order() -> None:
    result = compile_(EXAMPLE / "td.reference-dialect.json")
    positions = [(d.line or 0, d.col or 0) for d in result.diagnostics]
    assert positions == sorted(positions)


def _migrated(sources: Any, tmp_path: Path) -> tuple[Model, Model]:
    before = compile_(sources)
    assert before.model is not None and before.input is not None
    notes = Diagnostics()
    td = migrate(before.input.td, before.model, notes, legacy=before.input.kind == "legacy")
    out = tmp_path / "migrated.json"
    out.write_text(json.dumps(td, indent=2))
    after = compile_(out)
    assert after.model is not None, [d.message for d in after.diagnostics if d.severity is Severity.ERROR]
    assert after.dialects == frozenset({"rosv"})
    assert not [d for d in after.diagnostics if d.code.startswith(("TD1", "ROS4")) and d.severity is Severity.WARNING]
    return before.model, after.model


def test_migrate_reference_dialect_keeps_the_model(tmp_path: Path) -> None:
    before, after = _migrated(EXAMPLE / "td.reference-dialect.json", tmp_path)
    assert after == before


def test_migrate_legacy_config_keeps_the_model(tmp_path: Path) -> None:
    before, after = _migrated(LEGACY, tmp_path)
    assert after == before
    assert [c.name for c in after.components][:2] == ["GoToComponent", "PickComponent"]
    assert after.component("GoToComponent").procedures[0].cancel == "gotoCancle"


def test_migrated_td_passes_the_official_schema(tmp_path: Path) -> None:
    import jsonschema

    before = compile_(EXAMPLE / "td.reference-dialect.json")
    assert before.model is not None and before.input is not None
    td = migrate(before.input.td, before.model, Diagnostics(), legacy=False)
    schema = wot_corpus.official_json("td-schema-v1.1.json")
    validator = jsonschema.Draft7Validator(schema, format_checker=jsonschema.FormatChecker())
    assert [e.message for e in validator.iter_errors(td)] == []
    for name in ("td.json",):
        assert [e.message for e in validator.iter_errors(json.loads((EXAMPLE / name).read_text()))] == []


# ---------------------------------------------------------------------------------------------------------
# ROS rules, each with its diagnostic


def _td_with(mutate: Any) -> dict[str, Any]:
    td = json.loads((EXAMPLE / "td.json").read_text())
    mutate(td)
    return td


def _codes(td: dict[str, Any], tmp_path: Path, **kw: Any) -> Result:
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td, indent=2))
    return compile_(path, **kw)


def _form(td: dict[str, Any], group: str, name: str) -> dict[str, Any]:
    form: dict[str, Any] = td[group][name]["forms"][0]
    return form


CASES = {
    "unknown type": (
        lambda td: _form(td, "actions", "gotoRun").update({"rosv:type": "robot_local_control_msgs/srv/GoToPetitio"}),
        "ROS423",
        "/actions/gotoRun/forms/0/rosv:type",
    ),
    "malformed type": (
        lambda td: _form(td, "actions", "gotoRun").update({"rosv:type": "not a type"}),
        "ROS420",
        "/actions/gotoRun/forms/0/rosv:type",
    ),
    "msg type on a service": (
        lambda td: _form(td, "actions", "gotoRun").update({"rosv:type": "std_msgs/msg/Float64"}),
        "ROS421",
        "/actions/gotoRun/forms/0/rosv:type",
    ),
    "bad ROS name": (
        lambda td: _form(td, "properties", "door").update({"rosv:name": "/door1//command"}),
        "ROS410",
        "/properties/door/forms/0/rosv:name",
    ),
    "bad role": (
        lambda td: _form(td, "properties", "door").update({"rosv:role": "server"}),
        "ROS407",
        "/properties/door/forms/0/rosv:role",
    ),
    "same name two types": (
        lambda td: _form(td, "actions", "gotoCancel").update(
            {"rosv:name": _form(td, "actions", "gotoRun")["rosv:name"]}
        ),
        "ROS414",
        "/actions/gotoCancel/forms/0/rosv:type",
    ),
    "component keyword": (
        lambda td: td["properties"]["door"].update({"rosv:component": "class"}),
        "ROS430",
        "/properties/door/rosv:component",
    ),
    "unbound action": (
        lambda td: td["actions"]["gotoRun"].update({"forms": [{"href": "http://x/y"}]}),
        "ROS401",
        "/actions/gotoRun",
    ),
    "procedure link to nothing": (
        lambda td: td["actions"]["gotoRun"]["rosv:procedure"].update({"query": "nope"}),
        "ROS442",
        "/actions/gotoRun/rosv:procedure/query",
    ),
    "procedure link to self": (
        lambda td: td["actions"]["gotoRun"]["rosv:procedure"].update({"cancel": "gotoRun"}),
        "ROS443",
        "/actions/gotoRun/rosv:procedure/cancel",
    ),
    "mission id not in response": (
        lambda td: td["actions"]["gotoRun"]["rosv:procedure"].update({"missionId": "state/header/nope"}),
        "ROS444",
        "/actions/gotoRun/rosv:procedure/missionId",
    ),
    "bad QoS": (
        lambda td: _form(td, "properties", "door").update({"rosv:qos": {"reliability": "sometimes"}}),
        "ROS408",
        "/properties/door/forms/0/rosv:qos/reliability",
    ),
    "two ROS forms": (
        lambda td: td["actions"]["gotoRun"]["forms"].append(copy.deepcopy(_form(td, "actions", "gotoRun"))),
        "ROS402",
        "/actions/gotoRun/forms/1",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_ros_rules(case: str, tmp_path: Path) -> None:
    mutate, code, pointer = CASES[case]
    result = _codes(_td_with(mutate), tmp_path)
    assert result.model is None
    hits = [d for d in result.diagnostics if d.code == code]
    assert hits, [(d.code, d.message) for d in result.diagnostics]
    assert hits[0].pointer == pointer and hits[0].line is not None and hits[0].severity is Severity.ERROR


def test_unknown_type_names_the_closest(tmp_path: Path) -> None:
    td = _td_with(CASES["unknown type"][0])
    (diag,) = [d for d in _codes(td, tmp_path).diagnostics if d.code == "ROS423"]
    assert diag.hint is not None and "robot_local_control_msgs/srv/GoToPetition" in diag.hint


def test_declared_java_types_must_match(tmp_path: Path) -> None:
    td = json.loads((EXAMPLE / "td.reference-dialect.json").read_text())
    td["actions"]["gotoRun"]["forms"][0]["ros:serviceRequestType"] = "robot_local_control_msgs.PickPetitionRequest"
    result = _codes(td, tmp_path)
    (diag,) = [d for d in result.diagnostics if d.code == "ROS422"]
    assert "GoToPetitionRequest" in diag.message and diag.pointer.endswith("ros:serviceRequestType")


def test_strict_turns_warnings_into_errors(tmp_path: Path) -> None:
    result = compile_(EXAMPLE / "td.reference-dialect.json", strict=True)
    assert result.model is None and not result.ok
    assert not [d for d in result.diagnostics if d.severity is Severity.WARNING]


def test_no_ros_binding_is_a_warning_not_an_error() -> None:
    result = td2adaptor.compile(wot_corpus.require_corpus().file("valid/MinimalThing.json"))
    assert result.ok and "ROS400" in [d.code for d in result.diagnostics]


def test_broken_interface_files_the_td_does_not_use_are_warnings(tmp_path: Path) -> None:
    """An interface folder as ROS 1 users have them: genmsg-only spellings and a broken file the TD never uses
    do not fail the compile; a broken file the TD needs does."""
    extra = tmp_path / "extra"
    (extra / "odom_msgs" / "srv").mkdir(parents=True)
    (extra / "odom_msgs" / "msg").mkdir(parents=True)
    (extra / "odom_msgs" / "srv" / "set_odometry.srv").write_text("float64 x\n---\nbool ok\n")
    (extra / "odom_msgs" / "srv" / "Reset.srv").write_text("bool hard\n-----\nbool ok\n")
    (extra / "odom_msgs" / "msg" / "Broken.msg").write_text("int32\n")
    dirs = [EXAMPLE / "interfaces", extra]
    result = td2adaptor.compile(EXAMPLE / "td.json", interfaces=dirs)
    assert result.model is not None, [d.message for d in result.diagnostics]
    found = {(d.code, d.severity) for d in result.diagnostics if d.severity is not Severity.INFO}
    assert found == {("TY517", Severity.WARNING), ("TY510", Severity.WARNING)}
    broken = next(d for d in result.diagnostics if d.code == "TY510")
    assert broken.file is not None and broken.file.endswith("Broken.msg") and "uses no type" in broken.message
    # the same broken message, used by the TD: an error
    td = json.loads((EXAMPLE / "td.json").read_text())
    td["properties"]["door"]["forms"][0]["rosv:type"] = "odom_msgs/msg/Broken"
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td))
    failed = td2adaptor.compile(path, interfaces=dirs)
    assert failed.model is None
    assert any(d.code == "TY510" and d.severity is Severity.ERROR for d in failed.diagnostics)


def test_interface_file_diagnostics_are_located_in_the_file_whatever_the_input(tmp_path: Path) -> None:
    (tmp_path / "demo_msgs" / "msg").mkdir(parents=True)
    (tmp_path / "demo_msgs" / "msg" / "Broken.msg").write_text("bool ok\n\nuint8  \n")
    (tmp_path / "BadPkg" / "msg").mkdir(parents=True)
    (tmp_path / "BadPkg" / "msg" / "X.msg").write_text("int32 x\n")
    broken = str(tmp_path / "demo_msgs" / "msg" / "Broken.msg")
    legacy = [REPO / "tests" / "data" / "legacy" / "service.json", REPO / "tests" / "data" / "legacy" / "topic.json"]
    for sources, dirs in (([EXAMPLE / "td.json"], [EXAMPLE / "interfaces", tmp_path]), (legacy, [tmp_path])):
        result = td2adaptor.compile(sources, interfaces=dirs)
        [found] = [d for d in result.diagnostics if d.code == "TY510"]
        assert (found.file, found.line) == (broken, 3), sources
        [folder] = [d for d in result.diagnostics if d.code == "TY502"]  # about a folder: no line, no column
        assert (folder.file, folder.line, folder.col) == (str(tmp_path / "BadPkg"), None, None), sources


def test_ros1_type_spellings_and_relative_names_in_a_fleet_td_are_warned(tmp_path: Path) -> None:
    text = (REPO / "tests" / "golden" / "cases" / "std_robot" / "td.json").read_text()
    text = text.replace('"/{{robotName}}/odom"', '"odom"').replace('"std_srvs/srv/SetBool"', '"std_srvs/SetBool"')
    path = tmp_path / "td.json"
    path.write_text(text)
    result = td2adaptor.compile(path)
    assert result.model is not None
    found = {d.code: d for d in result.diagnostics}
    assert found["ROS427"].hint == "write 'std_srvs/srv/SetBool', the binding's form"
    assert "relative" in found["ROS416"].message and "/{{robotName}}/odom" in (found["ROS416"].hint or "")
    assert found["ROS416"].pointer.endswith("/rosv:name") and found["ROS427"].pointer.endswith("/rosv:type")


def test_standard_interface_packages_are_named_with_what_installs_them() -> None:
    std = td2adaptor.compile(REPO / "tests" / "golden" / "cases" / "std_robot" / "td.json")
    named = {d.message.split()[0]: d.hint for d in std.diagnostics if d.code == "ROS428"}
    assert sorted(named) == ["geometry_msgs", "nav_msgs", "sensor_msgs", "std_srvs"]
    assert named["sensor_msgs"] == (
        "ROS 2: pip install ros-jazzy-sensor-msgs (or your ROS 2 distribution's package); "
        "ROS 1: apt install python3-sensor-msgs"
    )
    # the RB-1's own packages come from --interfaces: only the standard one it binds to is named
    rb1 = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[EXAMPLE / "interfaces"])
    assert [d.message.split()[0] for d in rb1.diagnostics if d.code == "ROS428"] == ["std_msgs"]


def test_a_rosclasses_name_used_twice_is_renamed_with_a_warning(tmp_path: Path) -> None:
    """Like the reference's topic-test.json: a Subscriber and a Publisher of one name in one class; the
    reference generated both, so the later one is renamed rather than the file refused."""
    test = {
        "RosClasses": [
            {
                "ClassName": "TestComponent",
                "Topics": [
                    {"Role": "Subscriber", "ReferenceName": "door", "TopicName": "/door1/state",
                     "TopicType": "std_msgs/Float64", "MessageType": "std_msgs.Float64"},
                    {"Role": "Publisher", "ReferenceName": "door", "TopicName": "/door1/door_controller/command",
                     "TopicType": "std_msgs/Float64", "MessageType": "std_msgs.Float64"},
                ],
            }
        ]
    }  # fmt: skip
    path = tmp_path / "topic-test.json"
    path.write_text(json.dumps(test, indent=2))
    result = td2adaptor.compile(path)
    assert result.model is not None, [d.message for d in result.diagnostics]
    [renamed] = [d for d in result.diagnostics if d.code == "MIG704"]
    assert renamed.severity is Severity.WARNING and "becomes 'door2'" in renamed.message
    assert renamed.file == str(path) and renamed.line is not None
    (component,) = result.model.components
    assert [t.name for t in component.topics] == ["door", "door2"]


def test_the_model_knows_which_interface_packages_are_standard() -> None:
    rb1 = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[EXAMPLE / "interfaces"]).model
    assert rb1 is not None and rb1.standard_packages == ("builtin_interfaces", "geometry_msgs", "std_msgs")
    std = td2adaptor.compile(REPO / "tests" / "golden" / "cases" / "std_robot" / "td.json").model
    assert std is not None and {"nav_msgs", "sensor_msgs", "std_srvs"} <= set(std.standard_packages)
