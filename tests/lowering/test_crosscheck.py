"""Cross-check of TD data schemas against ROS messages, on the reference TD's known defects (brainiot §1.6).

Type tables are built by hand from the field lists of the RB-1 interface (brainiot §5), so these tests do not
depend on a type registry. The schemas reproduce the shapes the reference TD uses, defects included.
"""

from __future__ import annotations

import copy
import re
from typing import Any

import pytest

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.lowering.crosscheck import CODES, crosscheck
from td2adaptor.model import ArrayKind, Constant, FieldType, MessageDef, MessageField, TypeTable

_ARRAY = re.compile(r"^(?P<base>[^\[]+)(\[(?P<bound><=)?(?P<n>\d*)\])?$")


def ftype(spec: str) -> FieldType:
    """`float64`, `pkg/msg/Name[]`, `float64[36]`, `int32[<=3]`, `string<=8` → FieldType."""
    m = _ARRAY.match(spec)
    assert m is not None, spec
    base, string_bound = m["base"], 0
    if "<=" in base:
        base, bound = base.split("<=")
        string_bound = int(bound)
    if m.group(2) is None:
        array, length = ArrayKind.NONE, 0
    elif m["bound"] or not m["n"]:
        array, length = ArrayKind.SEQUENCE, int(m["n"] or 0)
    else:
        array, length = ArrayKind.FIXED, int(m["n"])
    return FieldType(base, "/" in base, array, length, string_bound)


def msg(name: str, fields: str, constants: dict[str, Any] | None = None, ctype: str = "string") -> MessageDef:
    """`msg("pkg/msg/N", "a:int32 b:pkg/msg/M[]", {"OK": "ok"})`."""
    parsed = tuple(MessageField(n, ftype(t)) for n, t in (f.split(":", 1) for f in fields.split()))
    consts = tuple(Constant(k, ctype, v) for k, v in (constants or {}).items())
    return MessageDef(name, parsed, consts)


RLC = "robot_local_control_msgs/msg/"
PROC = "procedures_msgs/msg/"
HEADER = "std_msgs/msg/Header"

_STATES = "queued running paused finished unknown added start stop cancel pause resume finish abort"
_STATE_CONSTANTS = {n.upper(): n for n in _STATES.split()}

ROS1_MESSAGES = (
    msg(HEADER, "seq:uint32 stamp:time frame_id:string"),
    msg("std_msgs/msg/String", "data:string"),
    msg("geometry_msgs/msg/Pose2D", "x:float64 y:float64 theta:float64"),
    msg("geometry_msgs/msg/Point", "x:float64 y:float64 z:float64"),
    msg("geometry_msgs/msg/Quaternion", "x:float64 y:float64 z:float64 w:float64"),
    msg("geometry_msgs/msg/Pose", "position:geometry_msgs/msg/Point orientation:geometry_msgs/msg/Quaternion"),
    msg("geometry_msgs/msg/PoseStamped", f"header:{HEADER} pose:geometry_msgs/msg/Pose"),
    msg(RLC + "Pose2DStamped", f"header:{HEADER} pose:geometry_msgs/msg/Pose2D"),
    msg(RLC + "Twist2D", "linear_x:float64 linear_y:float64 angular_z:float64"),
    msg(RLC + "GoTo", f"goals:{RLC}Pose2DStamped[] max_velocities:{RLC}Twist2D[]"),
    msg("robot_local_control_msgs/srv/GoToPetition_Request", f"procedure:{RLC}GoTo"),
    msg(
        "robot_local_control_msgs/srv/GoToPetition_Response",
        f"state:{PROC}ProcedureState result:{PROC}ProcedureResult",
    ),
    msg(PROC + "ProcedureHeader", "id:int32 priority:int32 stamp:time name:string"),
    msg(
        PROC + "ProcedureState",
        f"header:{PROC}ProcedureHeader current_state:string last_event:string",
        _STATE_CONSTANTS,
    ),
    msg(PROC + "ProcedureResult", "result:string message:string", {"OK": "ok", "ERROR": "error"}),
    msg("procedures_msgs/srv/ProcedureQuery_Request", f"header:{PROC}ProcedureHeader"),
    msg(
        "procedures_msgs/srv/ProcedureQuery_Response",
        f"state:{PROC}ProcedureState result:{PROC}ProcedureResult last_message:std_msgs/msg/String",
    ),
    msg(
        RLC + "Status",
        f"robot_id:string robot_state:string control_state:string operation_state:string "
        f"mission_status:{RLC}Missions localization_status:{RLC}LocalizationStatus "
        f"navigation_status:{RLC}NavigationStatus robot_status:{RLC}RobotStatus",
        {"ROBOT_STATE_READY": "ready", "ROBOT_STATE_FAILURE": "failure", "CONTROL_STATE_AUTO": "auto"},
    ),
    msg(RLC + "Missions", f"current:{RLC}MissionStatus last:{RLC}MissionStatus[]"),
    msg(RLC + "MissionStatus", "id:int32 description:string state:string"),
    msg(
        RLC + "LocalizationStatus",
        f"pose:{RLC}Pose2DStamped reliable:bool node:string type:string state:string",
        {
            "LOCALIZATION_TYPE_NONE": "none",
            "LOCALIZATION_TYPE_1": "1",
            "LOCALIZATION_STATE_READY": "ready",
            "LOCALIZATION_STATE_FAILURE": "failure",
        },
    ),
    msg(RLC + "NavigationStatus", "type:string state:string"),
    msg(
        RLC + "RobotStatus",
        f"battery:robotnik_msgs/msg/BatteryStatus emergency_stop:bool pose:{RLC}Pose2DStamped "
        f"velocity:{RLC}Twist2D safety_status:robotnik_msgs/msg/SafetyModuleStatus "
        f"battery_docking_status:robotnik_msgs/msg/BatteryDockingStatus sensors:{RLC}SensorStatus[] "
        "elevator:robotnik_msgs/msg/ElevatorStatus",
    ),
    msg(RLC + "SensorStatus", "name:string type:string state:string"),
    msg(
        "robotnik_msgs/msg/BatteryStatus",
        "voltage:float32 level:float32 time_remaining:uint32 time_charging:uint32 is_charging:bool",
    ),
    msg("robotnik_msgs/msg/ElevatorStatus", "state:string position:string"),
    msg(
        "ar_track_alvar_msgs/msg/AlvarMarkers",
        f"header:{HEADER} markers:ar_track_alvar_msgs/msg/AlvarMarker[]",
    ),
    msg(
        "ar_track_alvar_msgs/msg/AlvarMarker",
        f"header:{HEADER} id:uint32 confidence:uint32 pose:geometry_msgs/msg/PoseStamped",
    ),
)
ROS1 = TypeTable("ros1", ROS1_MESSAGES)

GOTO_REQ = "robot_local_control_msgs/srv/GoToPetition_Request"
QUERY_REQ = "procedures_msgs/srv/ProcedureQuery_Request"
QUERY_RES = "procedures_msgs/srv/ProcedureQuery_Response"
STATUS = RLC + "Status"
MARKERS = "ar_track_alvar_msgs/msg/AlvarMarkers"


def obj(**props: Any) -> dict[str, Any]:
    return {"type": "object", "properties": props}


INT: dict[str, Any] = {"type": "integer"}
NUM: dict[str, Any] = {"type": "number"}
STR: dict[str, Any] = {"type": "string"}
BOOL: dict[str, Any] = {"type": "boolean"}


def stamp_with_header_fields() -> dict[str, Any]:
    """The reference TD's stamp: `frame_id` and `seq` beside `properties` instead of in the header."""
    return {"type": "object", "properties": {"secs": INT, "nsecs": INT}, "frame_id": STR, "seq": INT}


def good_header() -> dict[str, Any]:
    return obj(seq=INT, stamp=obj(secs=INT, nsecs=INT), frame_id=STR)


def pose2d_stamped(header: dict[str, Any]) -> dict[str, Any]:
    return obj(header=header, pose=obj(x=NUM, y=NUM, theta=NUM))


def goto_input(header: dict[str, Any]) -> dict[str, Any]:
    return obj(
        procedure=obj(
            goals={"type": "array", "minItems": 1, "maxItems": 32, "items": pose2d_stamped(header)},
            max_velocities={
                "type": "array",
                "minItems": 1,
                "maxItems": 32,
                "items": obj(linear_x=NUM, linear_y=NUM, angular_z=NUM),
            },
        )
    )


def run(schema: Any, name: str, table: TypeTable = ROS1, pointer: str = "/x", label: str = "") -> Diagnostics:
    diags = Diagnostics()
    before = copy.deepcopy(schema)
    crosscheck(schema, pointer, name, table, diags, label=label)
    assert schema == before, "cross-check must not modify the schema"
    for d in diags:
        assert d.code in CODES, d
    return diags


def only(diags: Diagnostics, code: str) -> list[Diagnostic]:
    return [d for d in diags if d.code == code]


def one(diags: Diagnostics, code: str, pointer: str) -> Diagnostic:
    found = [d for d in diags if d.code == code and d.pointer == pointer]
    assert len(found) == 1, (code, pointer, [(d.code, d.pointer) for d in diags])
    return found[0]


GOALS = "/actions/gotoRun/input/properties/procedure/properties/goals"


# -- item 5: frame_id and seq beside `properties` in `stamp` --


def test_goto_input_misplaced_header_fields() -> None:
    diags = run(goto_input(obj(stamp=stamp_with_header_fields())), GOTO_REQ, pointer="/actions/gotoRun/input")
    stamp = f"{GOALS}/items/properties/header/properties/stamp"
    frame_id = one(diags, "XC603", f"{stamp}/frame_id")
    assert frame_id.severity is Severity.WARNING
    assert "misplaced field" in frame_id.message
    assert f"`procedure.goals[].header.frame_id` of `{GOTO_REQ}`" in frame_id.message
    assert frame_id.hint is not None and "procedure.goals[].header" in frame_id.hint
    seq = one(diags, "XC603", f"{stamp}/seq")
    assert "`procedure.goals[].header.seq`" in seq.message
    # the misplaced fields are not reported a second time as missing from the header
    assert not only(diags, "XC602")
    assert not only(diags, "XC601")


def test_goto_input_min_items_is_only_info() -> None:
    diags = run(goto_input(good_header()), GOTO_REQ, pointer="/actions/gotoRun/input")
    infos = only(diags, "XC608")
    assert {d.pointer for d in infos} == {
        f"{GOALS}/minItems",
        "/actions/gotoRun/input/properties/procedure/properties/max_velocities/minItems",
    }
    assert all(d.severity is Severity.INFO for d in infos)
    assert not diags.warnings()


def test_correct_goto_input_has_no_findings() -> None:
    schema = goto_input(good_header())
    for key in ("goals", "max_velocities"):
        del schema["properties"]["procedure"]["properties"][key]["minItems"]
    assert len(run(schema, GOTO_REQ)) == 0


# -- item 6: title vs name, id string vs int32 and number vs int32 --


def procedure_header(id_schema: dict[str, Any], name_key: str) -> dict[str, Any]:
    return {
        "type": "object",
        "properties": {"id": id_schema, "priority": INT, "stamp": obj(secs=INT, nsecs=INT), name_key: STR},
    }


def test_query_input_title_and_string_id() -> None:
    schema = obj(header=procedure_header(STR, "title"))
    diags = run(schema, QUERY_REQ, pointer="/actions/gotoQuery/input", label="input of action `gotoQuery`")
    base = "/actions/gotoQuery/input/properties/header/properties"
    title = one(diags, "XC601", f"{base}/title")
    assert title.hint == "did you mean `name`?"
    assert f"`header` of `{QUERY_REQ}`" in title.message
    assert title.message.startswith("input of action `gotoQuery`: ")
    id_type = one(diags, "XC604", f"{base}/id/type")
    assert f"`header.id` of `{QUERY_REQ}` is int32" in id_type.message
    assert "`string`" in id_type.message
    assert id_type.hint == 'use "type": "integer"'
    # `name` is the suggestion for `title`, not reported again as missing
    assert not only(diags, "XC602")
    assert len(diags) == 2


def test_pick_query_input_with_name_and_integer_id_is_clean() -> None:
    assert len(run(obj(header=procedure_header(INT, "name")), QUERY_REQ)) == 0


def query_output(id_schema: dict[str, Any], name_key: str) -> dict[str, Any]:
    return obj(
        _format=STR,
        state=obj(
            header=procedure_header(id_schema, name_key),
            current_state={"type": "string", "enum": ["queued", "running", "paused", "finished", "unknown"]},
            last_event={
                "type": "string",
                "enum": ["added", "start", "stop", "cancel", "pause", "resume", "finish", "abort"],
            },
        ),
        result=obj(message=STR, result={"type": "string", "enum": ["ok", "error"]}),
    )


def test_query_output_extra_format_number_id_and_missing_last_message() -> None:
    diags = run(query_output(NUM, "title"), QUERY_RES, pointer="/actions/gotoQuery/output")
    base = "/actions/gotoQuery/output/properties"
    fmt = one(diags, "XC601", f"{base}/_format")
    assert fmt.hint is not None and "did you mean" not in fmt.hint  # `_format` is no `last_message`
    missing = one(diags, "XC602", f"{base}")
    assert "`last_message`" in missing.message and f"of `{QUERY_RES}`" in missing.message
    id_num = one(diags, "XC605", f"{base}/state/properties/header/properties/id/type")
    assert "`state.header.id`" in id_num.message
    assert one(diags, "XC601", f"{base}/state/properties/header/properties/title").hint == "did you mean `name`?"
    assert not only(diags, "XC609")  # enums agree with the ProcedureState / ProcedureResult constants
    assert len(diags) == 4


# -- items 4, 7, 8: robot_local_control_msgs/Status ("availability") --


def availability() -> dict[str, Any]:
    pose = pose2d_stamped(obj(stamp=stamp_with_header_fields()))
    return {
        "type": "object",
        "description": "robot state",
        "observable": True,
        "readOnly": True,
        "forms": [{"href": "", "op": ["readproperty", "observeproperty"]}],
        "properties": {
            "robot_id": STR,
            "robot_state": {"type": "string", "enum": ["init", "standby", "ready", "emergency", "failure"]},
            "control_state": STR,
            "operation_state": STR,
            "mission_status": obj(current=obj(id=INT, description=STR, state=STR), last=obj(id=INT, state=STR)),
            "localization_status": obj(
                pose=pose,
                reliable=BOOL,
                node=INT,
                rtype=STR,
                state={"type": "string", "enum": ["ready", "failure", "lost"]},
            ),
            "navigation_status": obj(ntype=STR, state=STR),
            "robot_status": obj(
                battery=obj(
                    voltage=NUM,
                    **{"level:": NUM},
                    time_remaining=STR,
                    time_charging=STR,
                    is_charging=BOOL,
                ),
                emergency_stop=BOOL,
                pose=pose,
                velocity=obj(linear_x=NUM, linear_y=NUM, angular_z=NUM),
                sensors=obj(title=STR, stype=STR, state=STR),
                elevator=obj(state=INT, position=STR),
            ),
        },
    }


@pytest.fixture(scope="module")
def status_diags() -> Diagnostics:
    return run(availability(), STATUS, pointer="/properties/availability")


P = "/properties/availability/properties"


def test_level_with_trailing_colon(status_diags: Diagnostics) -> None:
    d = one(status_diags, "XC601", f"{P}/robot_status/properties/battery/properties/level:")
    assert d.hint == "did you mean `level`?"
    assert "`robot_status.battery`" in d.message and "robotnik_msgs/msg/BatteryStatus" in d.message
    # `level` is the fix for `level:`, so it is not listed as missing too
    assert not [x for x in only(status_diags, "XC602") if "battery" in x.pointer]


def test_type_spelled_ntype_rtype_stype(status_diags: Diagnostics) -> None:
    for where, key in (
        ("navigation_status", "ntype"),
        ("localization_status", "rtype"),
        ("robot_status/properties/sensors", "stype"),
    ):
        assert one(status_diags, "XC601", f"{P}/{where}/properties/{key}").hint == "did you mean `type`?"


def test_objects_instead_of_arrays(status_diags: Diagnostics) -> None:
    sensors = one(status_diags, "XC604", f"{P}/robot_status/properties/sensors/type")
    assert "`robot_status.sensors` of" in sensors.message
    assert f"{RLC}SensorStatus[]" in sensors.message and sensors.hint == 'use "type": "array"'
    last = one(status_diags, "XC604", f"{P}/mission_status/properties/last/type")
    assert "`mission_status.last`" in last.message
    # the element is still compared: sensors.title is ROS `name`
    title = one(status_diags, "XC601", f"{P}/robot_status/properties/sensors/properties/title")
    assert title.hint == "did you mean `name`?" and "`robot_status.sensors[]`" in title.message
    assert (
        "`mission_status.last[]`"
        in one(status_diags, "XC602", f"{P}/mission_status/properties/last/properties").message
    )


def test_scalar_type_mismatches(status_diags: Diagnostics) -> None:
    for path, ros, declared in (
        ("robot_status/properties/battery/properties/time_remaining", "uint32", "string"),
        ("robot_status/properties/battery/properties/time_charging", "uint32", "string"),
        ("robot_status/properties/elevator/properties/state", "string", "integer"),
        ("localization_status/properties/node", "string", "integer"),
    ):
        d = one(status_diags, "XC604", f"{P}/{path}/type")
        assert f" is {ros} but the schema declares type `{declared}`" in d.message


def test_missing_robot_status_fields(status_diags: Diagnostics) -> None:
    d = one(status_diags, "XC602", f"{P}/robot_status/properties")
    assert "`safety_status`" in d.message and "`battery_docking_status`" in d.message
    assert "`robot_status` of" in d.message
    assert "`sensors`" not in d.message


def test_misplaced_in_both_status_poses(status_diags: Diagnostics) -> None:
    pointers = {d.pointer for d in only(status_diags, "XC603")}
    stamp = "properties/pose/properties/header/properties/stamp"
    assert pointers == {
        f"{P}/{owner}/{stamp}/{key}" for owner in ("localization_status", "robot_status") for key in ("frame_id", "seq")
    }


def test_enum_checked_against_constants_named_after_the_field(status_diags: Diagnostics) -> None:
    d = one(status_diags, "XC609", f"{P}/localization_status/properties/state/enum")
    assert "'lost'" in d.message and "'none'" not in d.message.split("(", 1)[0]
    assert "LOCALIZATION_STATE_READY" in d.message and "LOCALIZATION_TYPE_NONE" not in d.message
    # robot_state: only ROBOT_STATE_* constants count, and init/standby/emergency are not among the two
    robot_state = one(status_diags, "XC609", f"{P}/robot_state/enum")
    assert "'init'" in robot_state.message and "'ready'" not in robot_state.message.split(" of ", 1)[0]


def test_affordance_members_are_not_misplaced_fields(status_diags: Diagnostics) -> None:
    assert not [d for d in status_diags if d.pointer.split("/")[-1] in ("forms", "observable", "readOnly")]


def test_status_findings_are_warnings_and_complete(status_diags: Diagnostics) -> None:
    assert all(d.severity is Severity.WARNING for d in status_diags)
    assert sorted(status_diags.codes()) == sorted(
        ["XC601"] * 5 + ["XC602"] * 2 + ["XC603"] * 4 + ["XC604"] * 6 + ["XC609"] * 2
    )


# -- items 5, 8, 9: ar_track_alvar_msgs/AlvarMarkers ("poseMarker") --


def pose_marker(header: dict[str, Any], marker: dict[str, Any], min_items: int | None = 1) -> dict[str, Any]:
    markers: dict[str, Any] = {"type": "array", "items": marker}
    if min_items is not None:
        markers["minItems"] = min_items
    return obj(header=header, markers=markers)


def pose_stamped(header: dict[str, Any]) -> dict[str, Any]:
    return obj(
        header=header,
        pose=obj(position=obj(x=NUM, y=NUM, z=NUM), orientation=obj(x=NUM, y=NUM, z=NUM, w=NUM)),
    )


def test_pose_marker_defects() -> None:
    bad_header = obj(stamp=stamp_with_header_fields())
    marker = obj(header=bad_header, confidence=INT, pose=pose_stamped(bad_header))
    diags = run(pose_marker(bad_header, marker), MARKERS, pointer="/properties/poseMarker")
    base = "/properties/poseMarker/properties"
    missing_id = one(diags, "XC602", f"{base}/markers/items/properties")
    assert "`id` (uint32)" in missing_id.message and "`markers[]` of" in missing_id.message
    assert "ar_track_alvar_msgs/msg/AlvarMarker`" in missing_id.message
    info = one(diags, "XC608", f"{base}/markers/minItems")
    assert info.severity is Severity.INFO and "may be empty" in info.message
    misplaced = {d.message.split("`")[1] for d in only(diags, "XC603")}
    assert misplaced == {
        f"{prefix}.{key}"
        for prefix in ("header", "markers[].header", "markers[].pose.header")
        for key in ("frame_id", "seq")
    }


def test_correct_pose_marker_has_no_findings() -> None:
    marker = obj(header=good_header(), id=INT, confidence=INT, pose=pose_stamped(good_header()))
    assert len(run(pose_marker(good_header(), marker, None), MARKERS)) == 0


# -- time and duration across distributions --

ROS2 = TypeTable(
    "ros2",
    (
        msg("std_msgs/msg/Header", "stamp:builtin_interfaces/msg/Time frame_id:string"),
        msg("builtin_interfaces/msg/Time", "sec:int32 nanosec:uint32"),
        msg("my_msgs/msg/Timer", "period:builtin_interfaces/msg/Duration"),
    ),
)


def test_ros2_time_written_the_ros1_way() -> None:
    diags = run(obj(stamp=obj(secs=INT, nsecs=INT), frame_id=STR), "std_msgs/msg/Header", ROS2)
    d = one(diags, "XC606", "/x/properties/stamp/properties")
    assert "sec/nanosec" in d.message and "secs/nsecs" in d.message
    assert len(diags) == 1
    assert len(run(obj(stamp=obj(sec=INT, nanosec=INT), frame_id=STR), "std_msgs/msg/Header", ROS2)) == 0
    # a Duration not in the table is still known by its members
    assert one(
        run(obj(period=obj(secs=INT, nsecs=INT)), "my_msgs/msg/Timer", ROS2),
        "XC606",
        "/x/properties/period/properties",
    )


def test_ros1_time_written_the_ros2_way_and_wrongly() -> None:
    header = obj(seq=INT, stamp=obj(sec=INT, nanosec=INT), frame_id=STR)
    assert run(header, HEADER).codes() == ["XC606"]
    header = obj(seq=INT, stamp=obj(secs=INT, nsec=INT), frame_id=STR)
    diags = run(header, HEADER)
    assert one(diags, "XC601", "/x/properties/stamp/properties/nsec").hint == "did you mean `nsecs`?"
    assert "`stamp.nsecs`" not in " ".join(d.message for d in diags)
    assert run(obj(seq=INT, stamp=STR, frame_id=STR), HEADER).codes() == ["XC604"]


def test_ros1_time_as_builtin_message_still_uses_ros1_names() -> None:
    """Registries such as rosbags spell ROS 1 `time` as builtin_interfaces/msg/Time; JSON keeps secs/nsecs."""
    table = TypeTable("ros1", (msg(HEADER, "seq:uint32 stamp:builtin_interfaces/msg/Time frame_id:string"),))
    assert len(run(good_header(), HEADER, table)) == 0
    assert run(obj(seq=INT, stamp=obj(sec=INT, nanosec=INT), frame_id=STR), HEADER, table).codes() == ["XC606"]


# -- arrays, ranges, loose types --

ARRAYS = TypeTable(
    "ros2",
    (
        msg(
            "a/msg/A",
            "cov:float64[36] few:int32[<=3] data:uint8[] bytes:byte[] "
            "small:uint8 big:uint32 name:string<=8 ratio:float32",
        ),
    ),
)


def arrays(**overrides: Any) -> dict[str, Any]:
    props: dict[str, Any] = {
        "cov": {"type": "array", "items": NUM, "minItems": 36, "maxItems": 36},
        "few": {"type": "array", "items": INT, "maxItems": 3},
        "data": {"type": "array", "items": INT},
        "bytes": {"type": "string", "contentEncoding": "base64"},
        "small": {"type": "integer", "minimum": 0, "maximum": 255},
        "big": INT,
        "name": {"type": "string", "maxLength": 8},
        "ratio": INT,
    }
    props.update(overrides)
    return obj(**props)


def test_arrays_and_ranges_consistent() -> None:
    assert len(run(arrays(), "a/msg/A", ARRAYS)) == 0


@pytest.mark.parametrize(
    ("override", "code", "pointer"),
    [
        ({"cov": {"type": "array", "items": NUM, "maxItems": 9}}, "XC607", "/x/properties/cov"),
        ({"few": {"type": "array", "items": INT, "maxItems": 5}}, "XC607", "/x/properties/few/maxItems"),
        ({"few": {"type": "array", "items": STR}}, "XC604", "/x/properties/few/items/type"),
        ({"data": {"type": "object"}}, "XC604", "/x/properties/data/type"),
        ({"small": {"type": "integer", "maximum": 300}}, "XC611", "/x/properties/small/maximum"),
        ({"big": {"type": "integer", "minimum": -1}}, "XC611", "/x/properties/big/minimum"),
        ({"name": {"type": "string", "maxLength": 80}}, "XC611", "/x/properties/name/maxLength"),
        ({"big": NUM}, "XC605", "/x/properties/big/type"),
        ({"ratio": STR}, "XC604", "/x/properties/ratio/type"),
        ({"ratio": {"type": ["number", "null"]}}, None, None),
        ({"data": {"type": "string", "contentEncoding": "base64"}}, None, None),
    ],
)
def test_array_and_range_rules(override: dict[str, Any], code: str | None, pointer: str | None) -> None:
    diags = run(arrays(**override), "a/msg/A", ARRAYS)
    if code is None:
        assert len(diags) == 0
    else:
        assert [(d.code, d.pointer) for d in diags] == [(code, pointer)]


def test_fixed_array_message_names_the_size() -> None:
    d = run(arrays(cov={"type": "array", "items": NUM, "minItems": 1}), "a/msg/A", ARRAYS).items[0]
    assert "float64[36]" in d.message and "exactly 36" in d.message and "at least 1" in d.message


# -- odd schemas: skipped, never a crash --


@pytest.mark.parametrize(
    "schema",
    [
        {},
        None,
        "object",
        [1, 2],
        {"$ref": "#/definitions/GoTo"},
        {"oneOf": [{"type": "object"}, {"type": "null"}]},
        {"type": "object"},
        {"type": "object", "properties": "procedure"},
        {"type": 7, "properties": {"procedure": {"allOf": []}}},
        obj(procedure=obj(goals={"type": "array", "items": [{"type": "object"}]}, max_velocities={})),
        obj(procedure=obj(goals={"type": "array", "items": {"anyOf": []}}, max_velocities={})),
        obj(procedure={"type": "object", "properties": {"goals": 5, "max_velocities": True}}),
    ],
)
def test_odd_schemas_are_skipped(schema: Any) -> None:
    assert len(run(schema, GOTO_REQ)) == 0


def test_unknown_message_and_unresolved_nested_types_are_skipped() -> None:
    assert len(run(obj(a=STR), "nope/msg/Nope")) == 0
    assert len(run(obj(a=STR), "procedures_msgs/srv/ProcedureQuery", TypeTable("ros1"))) == 0
    # safety_status is a message the table lacks: it is compared by name only
    table = TypeTable("ros1", (msg("r/msg/R", "safety_status:robotnik_msgs/msg/SafetyModuleStatus"),))
    assert len(run(obj(safety_status=obj(anything=STR)), "r/msg/R", table)) == 0


def test_deep_nesting_does_not_raise() -> None:
    table = TypeTable("ros1", (msg("r/msg/Node", "next:r/msg/Node[] value:int32"),))
    schema: dict[str, Any] = INT
    for _ in range(2000):
        schema = obj(next={"type": "array", "items": schema}, value=INT)
    diags = Diagnostics()
    crosscheck(schema, "", "r/msg/Node", table, diags)  # deeper than Python's recursion limit
    assert len(diags) == 0


def test_schema_members_named_like_keywords_are_not_misplaced() -> None:
    table = TypeTable("ros1", (msg("r/msg/S", "name:string type:string description:string"),))
    schema = {
        "type": "object",
        "description": "sensor",
        "properties": {"name": STR, "type": STR, "description": STR},
    }
    assert len(run(schema, "r/msg/S", table)) == 0
    # ...but a field name beside `properties` of its own message is
    schema = {"type": "object", "properties": {"type": STR, "description": STR}, "name": STR}
    assert run(schema, "r/msg/S", table).codes() == ["XC603"]


def test_a_tie_between_distros_goes_to_the_robots_own_ros(tmp_path: Any) -> None:
    import json

    import td2adaptor

    schema = {
        "type": "object",
        "properties": {
            "seq": {"type": "integer"},  # ROS 1 only
            "stamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nanosec": {"type": "integer"}}},
            "frame_id": {"type": "string"},
        },
    }
    form = {"href": "ros:///hdr", "rosv:name": "/hdr", "rosv:type": "std_msgs/msg/Header", "op": ["readproperty"]}
    td: dict[str, Any] = {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", {"rosv": "https://td2adaptor.dev/ros#"}],
        "title": "Tie",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": "nosec_sc",
        "properties": {"hdr": {**schema, "forms": [{**form, "rosv:component": "H"}]}},
    }

    def findings(master: bool) -> list[str]:
        path = tmp_path / f"tie-{master}.json"
        path.write_text(json.dumps({**td, **({"rosv:masterURI": "http://localhost:11311/"} if master else {})}))
        return [d.code for d in td2adaptor.compile(path).diagnostics if d.code.startswith("XC")]

    assert findings(master=False) == ["XC601"]  # read as ROS 2: `seq` is not a field
    assert findings(master=True) == ["XC606"]  # a ROS 1 robot: the stamp is a ROS 1 time in ROS 2 names
