"""ROS interface types: name normalisation, the type registry, and the RB-1 definitions' ROS 1 md5 sums."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.model import ActionDef, ArrayKind, FieldType, MessageDef, ServiceDef
from td2adaptor.rostypes import (
    CODES,
    TypeRegistry,
    action_part_names,
    is_valid_package_name,
    is_valid_type_name,
    normalize_type_name,
    parse_type_name,
    ros1_name,
    service_part_names,
    split_canonical,
)
from tests.conftest import EXAMPLE, REPO

RB1_INTERFACES = EXAMPLE / "interfaces"

# brainiot-edge-node.md section 5: ROS 1 md5 sums of the RB-1 interface (test vectors)
RB1_MD5 = {
    "procedures_msgs/msg/ProcedureHeader": "493985fca0cdb1fdc9c962db09efe534",
    "procedures_msgs/msg/ProcedureState": "6979cad7e83ce5406a65ccecf3686f85",
    "procedures_msgs/msg/ProcedureResult": "cad7f991fe633cf8d87eb04d33da9dfe",
    "procedures_msgs/srv/ProcedureQuery": "ed5e053c790e6fde7d83c20c942744f4",
    "robot_local_control_msgs/srv/GoToPetition": "6ac7730d0512afb89029d601f3754bbe",
    "robot_local_control_msgs/srv/PickPetition": "44c7093f5d45a75a03470d3d82ca14f6",
    "robot_local_control_msgs/srv/PlacePetition": "44c7093f5d45a75a03470d3d82ca14f6",
    "robot_local_control_msgs/msg/GoTo": "cc46f8689ca09285758e2ba1b6ef965a",
    "robot_local_control_msgs/msg/Pick": "39794562465f5c9f200e6d805267c9b2",
    "robot_local_control_msgs/msg/Place": "39794562465f5c9f200e6d805267c9b2",
    "robot_local_control_msgs/msg/Pose2DStamped": "b5f1e28823201bc5ea7e310fc49d253f",
    "robot_local_control_msgs/msg/Twist2D": "17086575cf04ea52ca33141c3079cb71",
    "robot_local_control_msgs/msg/RobotStatus": "90838ea3040050596aed5931529e77c5",
    "robot_local_control_msgs/msg/Status": "ca9792b66191252a9e02ed63b5d85e3b",
    "ar_track_alvar_msgs/msg/AlvarMarkers": "943fe17bfb0b4ea7890368d0b25ad0ad",
    "ar_track_alvar_msgs/msg/AlvarMarker": "ef2b6ad42bcb18e16b22fefb5c0fb85f",
}

# the types the RB-1 TD names (section 4)
RB1_TD_TYPES = [
    "robot_local_control_msgs/srv/GoToPetition",
    "procedures_msgs/srv/ProcedureQuery",
    "robot_local_control_msgs/srv/PickPetition",
    "robot_local_control_msgs/srv/PlacePetition",
    "robot_local_control_msgs/msg/Status",
    "ar_track_alvar_msgs/msg/AlvarMarkers",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "std_msgs/msg/Float64",
]


@pytest.fixture(scope="module")
def rb1_ros1() -> tuple[TypeRegistry, Diagnostics]:
    diags = Diagnostics()
    return TypeRegistry("ros1", [RB1_INTERFACES], diags), diags


@pytest.fixture(scope="module")
def rb1_ros2() -> tuple[TypeRegistry, Diagnostics]:
    diags = Diagnostics()
    return TypeRegistry("ros2", [RB1_INTERFACES], diags), diags


def write(root: Path, rel: str, text: str) -> Path:
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------------------------
# names


@pytest.mark.parametrize(
    ("raw", "kind", "expected"),
    [
        ("std_msgs/msg/String", None, "std_msgs/msg/String"),
        ("std_srvs/srv/Trigger", None, "std_srvs/srv/Trigger"),
        ("nav2_msgs/action/NavigateToPose", None, "nav2_msgs/action/NavigateToPose"),
        ("std_msgs/msg/String", "srv", "std_msgs/msg/String"),  # canonical wins over kind
        ("  std_msgs/String ", None, "std_msgs/msg/String"),
        ("std_msgs/String", "msg", "std_msgs/msg/String"),
        ("procedures_msgs/ProcedureQuery", "srv", "procedures_msgs/srv/ProcedureQuery"),
        ("pkg/Name", "action", "pkg/action/Name"),
        ("robot_local_control_msgs.Status", None, "robot_local_control_msgs/msg/Status"),
        ("robot_local_control_msgs.GoToPetition", "srv", "robot_local_control_msgs/srv/GoToPetition"),
        ("procedures_msgs.ProcedureQueryRequest", None, "procedures_msgs/srv/ProcedureQuery"),
        ("procedures_msgs.ProcedureQueryResponse", "srv", "procedures_msgs/srv/ProcedureQuery"),
        ("procedures_msgs/ProcedureQueryRequest", "srv", "procedures_msgs/srv/ProcedureQuery"),
        ("pkg/srv/Name_Request", None, "pkg/srv/Name"),
        # a message may legitimately end in Request
        ("moveit_msgs.MotionPlanRequest", "msg", "moveit_msgs/msg/MotionPlanRequest"),
        ("moveit_msgs/MotionPlanRequest", None, "moveit_msgs/msg/MotionPlanRequest"),
        # malformed
        ("", None, None),
        ("String", None, None),
        ("std_msgs/", None, None),
        ("/String", None, None),
        ("std_msgs//String", None, None),
        ("std_msgs/foo/String", None, None),
        ("a/b/c/D", None, None),
        ("Std_msgs/String", None, None),
        ("std-msgs/String", None, None),
        ("9pkg/String", None, None),
        ("std_msgs/string", None, None),
        ("std_msgs/Str_ing", None, None),
        ("std_msgs.String.Extra", None, None),
        ("std msgs/String", None, None),
        ("std_msgs/msg/", None, None),
    ],
)
def test_normalize_type_name(raw: str, kind: str | None, expected: str | None) -> None:
    assert normalize_type_name(raw, kind) == expected  # type: ignore[arg-type]


def test_parse_type_name_reports_the_service_half() -> None:
    req = parse_type_name("procedures_msgs.ProcedureQueryRequest")
    assert req is not None
    assert (req.canonical, req.part, req.message_name) == (
        "procedures_msgs/srv/ProcedureQuery",
        "request",
        "procedures_msgs/srv/ProcedureQuery_Request",
    )
    resp = parse_type_name("pkg/srv/Name_Response")
    assert resp is not None and resp.part == "response" and resp.message_name == "pkg/srv/Name_Response"
    goal = parse_type_name("pkg/action/Move_Goal")
    assert goal is not None and (goal.canonical, goal.part) == ("pkg/action/Move", "goal")
    plain = parse_type_name("std_msgs/String")
    assert plain is not None and plain.part is None and plain.message_name == "std_msgs/msg/String"


def test_service_part_names() -> None:
    assert service_part_names("procedures_msgs/srv/ProcedureQuery") == (
        "procedures_msgs/srv/ProcedureQuery_Request",
        "procedures_msgs/srv/ProcedureQuery_Response",
    )
    assert service_part_names("procedures_msgs/ProcedureQuery", "ros1") == (
        "procedures_msgs/ProcedureQueryRequest",
        "procedures_msgs/ProcedureQueryResponse",
    )
    # what the reference TD writes in ros:serviceRequestType / ros:serviceResponseType
    assert service_part_names("robot_local_control_msgs/GoToPetition", "java") == (
        "robot_local_control_msgs.GoToPetitionRequest",
        "robot_local_control_msgs.GoToPetitionResponse",
    )
    with pytest.raises(ValueError):
        service_part_names("std_msgs/msg/String")
    with pytest.raises(ValueError):
        service_part_names("not a name")
    assert action_part_names("pkg/action/Move") == (
        "pkg/action/Move_Goal",
        "pkg/action/Move_Result",
        "pkg/action/Move_Feedback",
    )
    with pytest.raises(ValueError):
        action_part_names("pkg/srv/Move")


def test_name_syntax_helpers() -> None:
    assert is_valid_package_name("robot_local_control_msgs")
    assert not is_valid_package_name("RobotMsgs")
    assert not is_valid_package_name("_msgs")
    assert not is_valid_package_name("2d_msgs")
    assert is_valid_type_name("Pose2DStamped")
    assert not is_valid_type_name("pose")
    assert not is_valid_type_name("Pose_2D")
    assert split_canonical("pkg/srv/Name_Request") == ("pkg", "srv", "Name_Request")
    assert split_canonical("pkg/Name") is None
    assert ros1_name("std_msgs/msg/Header") == "std_msgs/Header"


# ---------------------------------------------------------------------------------------------------------
# the RB-1 interface: ROS 1 md5 test vectors


def test_rb1_definitions_load_cleanly(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    _, diags = rb1_ros1
    assert list(diags) == []


@pytest.mark.parametrize(("name", "md5"), sorted(RB1_MD5.items()))
def test_rb1_ros1_md5(rb1_ros1: tuple[TypeRegistry, Diagnostics], name: str, md5: str) -> None:
    registry, _ = rb1_ros1
    assert registry.ros1_definition(name)[1] == md5


def test_rb1_ros1_full_text(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros1
    text, _ = registry.ros1_definition("robot_local_control_msgs/msg/Pose2DStamped")
    assert text == (
        "std_msgs/Header header\ngeometry_msgs/Pose2D pose\n"
        + "=" * 80
        + "\nMSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
        + "=" * 80
        + "\nMSG: geometry_msgs/Pose2D\nfloat64 x\nfloat64 y\nfloat64 theta\n"
    )
    srv_text, _ = registry.ros1_definition("procedures_msgs/srv/ProcedureQuery")
    assert srv_text == (
        "procedures_msgs/ProcedureHeader header\n---\n"
        "procedures_msgs/ProcedureState state\nprocedures_msgs/ProcedureResult result\n"
        "std_msgs/String last_message\n"
    )


def test_rb1_constants_keep_their_written_values(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros1
    loc = registry.resolve("robot_local_control_msgs/msg/LocalizationStatus")
    assert isinstance(loc, MessageDef)
    consts = {c.name: c for c in loc.constants}
    # a string constant spelled like a number stays a string
    assert consts["LOCALIZATION_TYPE_1"].value == "1"
    assert consts["LOCALIZATION_TYPE_1"].type == "string"
    state = registry.resolve("procedures_msgs/msg/ProcedureState")
    assert isinstance(state, MessageDef)
    assert [c.name for c in state.constants][:4] == ["QUEUED", "RUNNING", "PAUSED", "FINISHED"]
    assert [f.name for f in state.fields] == ["header", "current_state", "last_event"]


def test_ros1_md5_matches_rosbags_for_every_noetic_message() -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    registry = TypeRegistry("ros1")
    checked = 0
    for name in store.fielddefs:
        if name.startswith("builtin_interfaces/"):
            continue  # `time` and `duration` are primitives in ROS 1
        assert registry.ros1_definition(name) == store.generate_msgdef(name), name
        checked += 1
    assert checked > 150


def test_ros1_definition_errors(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros1
    with pytest.raises(KeyError):
        registry.ros1_definition("robot_local_control_msgs/msg/Nope")
    with pytest.raises(ValueError):
        TypeRegistry("ros2").ros1_definition("std_msgs/msg/Header")


# ---------------------------------------------------------------------------------------------------------
# distributions


def test_ros1_and_ros2_headers_differ(
    rb1_ros1: tuple[TypeRegistry, Diagnostics], rb1_ros2: tuple[TypeRegistry, Diagnostics]
) -> None:
    ros1, _ = rb1_ros1
    ros2, diags2 = rb1_ros2
    assert list(diags2) == []
    header1 = ros1.resolve("std_msgs/msg/Header")
    header2 = ros2.resolve("std_msgs/msg/Header")
    assert isinstance(header1, MessageDef) and isinstance(header2, MessageDef)
    assert [f.name for f in header1.fields] == ["seq", "stamp", "frame_id"]
    assert [f.name for f in header2.fields] == ["stamp", "frame_id"]
    assert header1.fields[1].type == FieldType("time")
    assert header2.fields[0].type == FieldType("builtin_interfaces/msg/Time", is_message=True)
    # `time` in a ROS 1-syntax user file follows the distribution too
    ph1, ph2 = (
        ros1.resolve("procedures_msgs/msg/ProcedureHeader"),
        ros2.resolve("procedures_msgs/msg/ProcedureHeader"),
    )
    assert isinstance(ph1, MessageDef) and isinstance(ph2, MessageDef)
    assert ph1.fields[2].type == FieldType("time")
    assert ph2.fields[2].type == FieldType("builtin_interfaces/msg/Time", is_message=True)
    assert ros1.resolve("builtin_interfaces/msg/Time") is None
    assert "builtin_interfaces/msg/Time" not in ros1.known_names()


def test_ros2_registry_resolves_the_rb1_names(rb1_ros2: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros2
    for name in [*RB1_MD5, *RB1_TD_TYPES]:
        assert registry.resolve(name) is not None, name
    table = registry.table(RB1_TD_TYPES)
    assert table.complete
    assert "builtin_interfaces/msg/Time" in [m.name for m in table.messages]
    goto = registry.resolve("robot_local_control_msgs/srv/GoToPetition")
    assert isinstance(goto, ServiceDef)
    assert goto.request.name == "robot_local_control_msgs/srv/GoToPetition_Request"
    assert goto.request.fields[0].type == FieldType("robot_local_control_msgs/msg/GoTo", is_message=True)
    assert [f.name for f in goto.response.fields] == ["state", "result"]
    gotomsg = registry.resolve("robot_local_control_msgs/msg/GoTo")
    assert isinstance(gotomsg, MessageDef)
    assert gotomsg.fields[0].type.array is ArrayKind.SEQUENCE


@pytest.mark.parametrize("distro", ["ros1", "ros2"])
def test_bundled_std_srvs(distro: str) -> None:
    registry = TypeRegistry(distro)  # type: ignore[arg-type]
    trigger = registry.resolve("std_srvs/srv/Trigger")
    assert isinstance(trigger, ServiceDef)
    assert trigger.request.fields == ()
    assert [(f.name, f.type.base) for f in trigger.response.fields] == [
        ("success", "bool"),
        ("message", "string"),
    ]
    set_bool = registry.resolve("std_srvs/srv/SetBool")
    assert isinstance(set_bool, ServiceDef)
    assert [f.name for f in set_bool.request.fields] == ["data"]
    empty = registry.resolve("std_srvs/srv/Empty")
    assert isinstance(empty, ServiceDef) and empty.request.fields == empty.response.fields == ()
    assert {"std_srvs/srv/Empty", "std_srvs/srv/SetBool", "std_srvs/srv/Trigger"} <= set(registry.known_names("srv"))
    if distro == "ros1":  # the well-known genpy md5 sums
        assert registry.ros1_definition("std_srvs/srv/Empty")[1] == "d41d8cd98f00b204e9800998ecf8427e"
        assert registry.ros1_definition("std_srvs/srv/Trigger")[1] == "937c9679a518e3a18d831e57125ea522"
        assert registry.ros1_definition("std_srvs/srv/SetBool")[1] == "09fb03525b03e7ea1fd3992bafd87e16"


# ---------------------------------------------------------------------------------------------------------
# type tables


def test_table_closure_order(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros1
    table = registry.table(["robot_local_control_msgs/srv/GoToPetition", "procedures_msgs/srv/ProcedureQuery"])
    assert table.distro == "ros1"
    assert [s.name for s in table.services] == [
        "robot_local_control_msgs/srv/GoToPetition",
        "procedures_msgs/srv/ProcedureQuery",
    ]
    # depth first, in field order, each message once where it is first used
    assert [m.name for m in table.messages] == [
        "robot_local_control_msgs/msg/GoTo",
        "robot_local_control_msgs/msg/Pose2DStamped",
        "std_msgs/msg/Header",
        "geometry_msgs/msg/Pose2D",
        "robot_local_control_msgs/msg/Twist2D",
        "procedures_msgs/msg/ProcedureState",
        "procedures_msgs/msg/ProcedureHeader",
        "procedures_msgs/msg/ProcedureResult",
        "std_msgs/msg/String",
    ]
    assert table.missing == ()
    assert table.get("std_msgs/msg/Header") is not None
    # deterministic: the same input gives the same table, in this and in a fresh registry
    assert registry.table(["robot_local_control_msgs/srv/GoToPetition", "procedures_msgs/srv/ProcedureQuery"]) == table
    again = TypeRegistry("ros1", [RB1_INTERFACES])
    assert again.table(["robot_local_control_msgs/srv/GoToPetition", "procedures_msgs/srv/ProcedureQuery"]) == table


def test_table_lists_missing_names(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros1
    table = registry.table(["std_msgs/msg/Nope", "std_msgs/msg/String", "std_msgs/msg/Nope", "other/srv/X"])
    assert table.missing == ("std_msgs/msg/Nope", "other/srv/X")
    assert [m.name for m in table.messages] == ["std_msgs/msg/String"]
    assert not table.complete


def test_resolving_is_fast_once_the_typestore_is_loaded() -> None:
    TypeRegistry("ros1")  # loads the per-process typestore
    start = time.perf_counter()
    registry = TypeRegistry("ros1", [RB1_INTERFACES])
    table = registry.table(RB1_TD_TYPES)
    for name in RB1_MD5:
        registry.ros1_definition(name)
    elapsed = time.perf_counter() - start
    assert table.complete
    assert elapsed < 0.1, f"{elapsed * 1000:.1f} ms"


def test_importing_does_not_load_rosbags() -> None:
    code = "import sys, td2adaptor.rostypes; assert not [m for m in sys.modules if m.startswith('rosbags')]"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


# ---------------------------------------------------------------------------------------------------------
# user interface folders


def test_srv_and_action_files_are_split(tmp_path: Path) -> None:
    write(
        tmp_path,
        "demo_msgs/srv/SetPoint.srv",
        "# comment\nuint8 MODE_A=1\nPoint target  # relative: demo_msgs/msg/Point\nuint8 mode\n"
        "---\nbool ok\nstring  message\n",
    )
    write(tmp_path, "demo_msgs/msg/Point.msg", "float64 x\nfloat64 y\n")
    write(tmp_path, "demo_msgs/action/Move.action", "Point goal\n---\nbool done\n---\nfloat32 progress\n")
    diags = Diagnostics()
    registry = TypeRegistry("ros2", [tmp_path], diags)
    assert list(diags) == []
    srv = registry.resolve("demo_msgs/srv/SetPoint")
    assert isinstance(srv, ServiceDef)
    assert srv.request.name == "demo_msgs/srv/SetPoint_Request"
    assert srv.request.fields[0].type == FieldType("demo_msgs/msg/Point", is_message=True)
    assert [(c.name, c.type, c.value) for c in srv.request.constants] == [("MODE_A", "uint8", 1)]
    assert [f.name for f in srv.response.fields] == ["ok", "message"]
    assert registry.resolve("demo_msgs/srv/SetPoint_Response") == srv.response
    action = registry.resolve("demo_msgs/action/Move")
    assert isinstance(action, ActionDef)
    assert (action.goal.name, action.result.name, action.feedback.name) == (
        "demo_msgs/action/Move_Goal",
        "demo_msgs/action/Move_Result",
        "demo_msgs/action/Move_Feedback",
    )
    assert action.feedback.fields[0].type == FieldType("float32")
    assert "demo_msgs/action/Move" in registry.known_names("action")
    assert "demo_msgs/srv/SetPoint_Request" not in registry.known_names()
    table = registry.table(["demo_msgs/action/Move", "demo_msgs/srv/SetPoint"])
    assert [m.name for m in table.messages] == ["demo_msgs/msg/Point"]
    assert len(table.actions) == 1 and len(table.services) == 1


def test_single_package_folder(tmp_path: Path) -> None:
    pkg = tmp_path / "demo_msgs"
    write(pkg, "msg/Point.msg", "float64 x\n")
    write(pkg, "srv/Get.srv", "---\nPoint p\n")
    registry = TypeRegistry("ros1", [pkg])
    assert isinstance(registry.resolve("demo_msgs/srv/Get"), ServiceDef)
    assert isinstance(registry.resolve("demo_msgs/msg/Point"), MessageDef)


def test_syntax_error_reports_file_and_line(tmp_path: Path) -> None:
    bad = write(tmp_path, "demo_msgs/msg/Bad.msg", "# fine\nfloat64 x\nfloat64\nint32 y 1 2\n")
    write(tmp_path, "demo_msgs/msg/User.msg", "Bad b\n")  # uses the broken type: no second error
    diags = Diagnostics()
    registry = TypeRegistry("ros1", [tmp_path], diags)
    errors = diags.errors()
    assert [(d.code, d.file, d.line) for d in errors] == [("TY510", str(bad), 3)]
    assert errors[0].col == 1
    assert errors[0].location == f"{bad}:3:1"
    assert registry.resolve("demo_msgs/msg/Bad") is None
    # ROS 1 has no default values: a warning, the value is dropped
    assert [(d.code, d.line, d.severity) for d in diags.warnings()] == [("TY515", 4, Severity.WARNING)]


@pytest.mark.parametrize(
    ("text", "code", "line"),
    [
        ("int32 x\nint32 x\n", "TY513", 2),
        ("int32 X=1\nint32 X=2\n", "TY513", 2),
        ("uint8 X=300\n", "TY512", 1),
        ("bool B=maybe\n", "TY512", 1),
        ("float64[] X=1\n", "TY512", 1),
        ("float64[0] x\n", "TY511", 1),
        ("int32<=5 x\n", "TY511", 1),
        ("other_pkg/srv/Thing x\n", "TY511", 1),
        ("int32 x-y\n", "TY510", 1),
        ("int32 x\n---\nint32 y\n", "TY514", 2),
        ("string<=5 s\n", "TY511", 1),  # bounded strings are ROS 2 only
    ],
)
def test_file_errors(tmp_path: Path, text: str, code: str, line: int) -> None:
    path = write(tmp_path, "demo_msgs/msg/Thing.msg", text)
    diags = Diagnostics()
    registry = TypeRegistry("ros1", [tmp_path], diags)
    assert [(d.code, d.file, d.line) for d in diags.errors()] == [(code, str(path), line)]
    assert code in CODES
    assert registry.resolve("demo_msgs/msg/Thing") is None


def test_bad_separator_count_in_srv(tmp_path: Path) -> None:
    path = write(tmp_path, "demo_msgs/srv/NoSep.srv", "int32 x\n")
    write(tmp_path, "demo_msgs/action/TwoParts.action", "int32 x\n---\nint32 y\n")
    diags = Diagnostics()
    registry = TypeRegistry("ros2", [tmp_path], diags)
    assert [(d.code, d.file) for d in diags.errors()] == [
        ("TY514", str(path)),
        ("TY514", str(tmp_path / "demo_msgs/action/TwoParts.action")),
    ]
    assert registry.resolve("demo_msgs/srv/NoSep") is None


def test_invalid_file_and_package_names(tmp_path: Path) -> None:
    write(tmp_path, "demo_msgs/msg/bad_name.msg", "int32 x\n")
    write(tmp_path, "demo_msgs/msg/9Digit.msg", "int32 x\n")
    write(tmp_path, "DemoMsgs/msg/Fine.msg", "int32 x\n")
    diags = Diagnostics()
    TypeRegistry("ros2", [tmp_path], diags)
    assert diags.codes() == ["TY502", "TY502", "TY502"]
    # genmsg builds a lower-case type name: for ROS 1 a warning (skipped: no TD can name it), not an error
    diags = Diagnostics()
    TypeRegistry("ros1", [tmp_path], diags)
    assert [(d.code, d.severity) for d in diags] == [
        ("TY502", Severity.ERROR),
        ("TY502", Severity.ERROR),
        ("TY517", Severity.WARNING),
    ]


def test_genmsg_separator_lines_are_ros1_only(tmp_path: Path) -> None:
    write(tmp_path, "demo_msgs/srv/SetOdometry.srv", "float64 x\n-----\nbool success\n")
    diags = Diagnostics()
    ros1 = TypeRegistry("ros1", [tmp_path], diags)
    assert [(d.code, d.severity, d.line) for d in diags] == [("TY517", Severity.WARNING, 2)]
    assert ros1.resolve("demo_msgs/srv/SetOdometry") is not None
    diags = Diagnostics()
    ros2 = TypeRegistry("ros2", [tmp_path], diags)
    assert ros2.resolve("demo_msgs/srv/SetOdometry") is None and "TY514" in diags.codes()


def test_missing_folder(tmp_path: Path) -> None:
    diags = Diagnostics()
    TypeRegistry("ros1", [tmp_path / "nope"], diags)
    assert diags.codes() == ["TY500"]
    empty = tmp_path / "empty"
    empty.mkdir()
    diags = Diagnostics()
    TypeRegistry("ros1", [empty], diags)
    assert [(d.code, d.severity) for d in diags] == [("TY501", Severity.WARNING)]


def test_undefined_type_names_the_field_and_suggests(tmp_path: Path) -> None:
    path = write(tmp_path, "demo_msgs/msg/Thing.msg", "int32 a\ngeometry_msgs/Pose2d pose\nUnknownLocal other\n")
    diags = Diagnostics()
    registry = TypeRegistry("ros1", [tmp_path], diags)
    errors = diags.errors()
    assert [(d.code, d.file, d.line) for d in errors] == [("TY520", str(path), 2), ("TY520", str(path), 3)]
    assert "'pose'" in errors[0].message and "geometry_msgs/msg/Pose2d" in errors[0].message
    assert errors[0].hint is not None and "geometry_msgs/msg/Pose2D" in errors[0].hint
    assert "demo_msgs/msg/UnknownLocal" in errors[1].message
    # the message itself resolves; its table reports what is missing
    table = registry.table(["demo_msgs/msg/Thing"])
    assert table.missing == ("geometry_msgs/msg/Pose2d", "demo_msgs/msg/UnknownLocal")


def test_closest_names(rb1_ros1: tuple[TypeRegistry, Diagnostics]) -> None:
    registry, _ = rb1_ros1
    assert registry.closest("geometry_msgs/msg/Pose2d")[0] == "geometry_msgs/msg/Pose2D"
    # the same type in another package (or of another kind) comes first
    assert registry.closest("std_msgs/msg/Pose")[0] == "geometry_msgs/msg/Pose"
    assert registry.closest("procedures_msgs/msg/ProcedureQuery")[0] == "procedures_msgs/srv/ProcedureQuery"
    assert registry.closest("robot_local_control_msgs/GoToPetitio")[0] == "robot_local_control_msgs/srv/GoToPetition"
    assert len(registry.closest("std_msgs/msg/Strin", n=2)) == 2
    assert registry.closest("zzzzzzzz/msg/Qqqqqqq") == []


def test_overriding_a_typestore_type_warns(tmp_path: Path) -> None:
    path = write(tmp_path, "std_msgs/msg/Header.msg", "time stamp\nstring frame_id\n")  # ROS 2 Header in ROS 1
    write(tmp_path, "std_msgs/msg/String.msg", "string data\n")  # identical: silent
    diags = Diagnostics()
    registry = TypeRegistry("ros1", [tmp_path], diags)
    assert [(d.code, d.severity, d.file) for d in diags] == [("TY530", Severity.WARNING, str(path))]
    header = registry.resolve("std_msgs/msg/Header")
    assert isinstance(header, MessageDef) and [f.name for f in header.fields] == ["stamp", "frame_id"]
    # messages from the typestore that use it see the override
    _, md5 = registry.ros1_definition("geometry_msgs/msg/PoseStamped")
    assert md5 != "d3812c3cbc69362b77dc0b19b345f8f5"


def test_overriding_a_bundled_or_earlier_definition_warns(tmp_path: Path) -> None:
    write(tmp_path / "a", "std_srvs/srv/Trigger.srv", "---\nbool success\n")
    write(tmp_path / "b", "std_srvs/srv/Trigger.srv", "---\nbool success\nstring message\nint32 code\n")
    diags = Diagnostics()
    registry = TypeRegistry("ros2", [tmp_path / "a", tmp_path / "b"], diags)
    assert diags.codes() == ["TY531", "TY531"]
    trigger = registry.resolve("std_srvs/srv/Trigger")
    assert isinstance(trigger, ServiceDef)
    assert [f.name for f in trigger.response.fields] == ["success", "message", "code"]  # later folder wins


def test_recursive_definitions_are_rejected(tmp_path: Path) -> None:
    write(tmp_path, "demo_msgs/msg/Node.msg", "Node[] children\n")
    write(tmp_path, "demo_msgs/msg/A.msg", "B b\n")
    write(tmp_path, "demo_msgs/msg/B.msg", "A[] a\n")
    diags = Diagnostics()
    registry = TypeRegistry("ros1", [tmp_path], diags)
    assert diags.codes() == ["TY521", "TY521"]
    assert registry.resolve("demo_msgs/msg/Node") is None
    assert registry.resolve("demo_msgs/msg/A") is None


def test_ros2_defaults_and_constants(tmp_path: Path) -> None:
    write(
        tmp_path,
        "demo_msgs/msg/Defaults.msg",
        'int32 count 5\nfloat64[] gains [1.0, 2.5]\nstring name "a # b"  # comment\n'
        "bool[2] flags [true, false]\n"
        "string<=3 short\nint32[<=4] few\n"
        'string GREETING="hi there"\nstring RAW=plain  # ROS 2 strips this comment\nint8 NEG=-5\n'
        "uint8 HEX=0x1F\n",
    )
    diags = Diagnostics()
    registry = TypeRegistry("ros2", [tmp_path], diags)
    assert list(diags) == []
    msg = registry.resolve("demo_msgs/msg/Defaults")
    assert isinstance(msg, MessageDef)
    assert [f.default for f in msg.fields] == [5, (1.0, 2.5), "a # b", (True, False), None, None]
    assert msg.fields[4].type == FieldType("string", string_bound=3)
    assert msg.fields[5].type == FieldType("int32", array=ArrayKind.SEQUENCE, length=4)
    assert [(c.name, c.value) for c in msg.constants] == [
        ("GREETING", "hi there"),
        ("RAW", "plain"),
        ("NEG", -5),
        ("HEX", 31),
    ]


def test_ros1_string_constants_are_everything_after_the_equals_sign(tmp_path: Path) -> None:
    write(tmp_path, "demo_msgs/msg/C.msg", 'string A = with # hash\nstring B="quoted"\n')
    registry = TypeRegistry("ros1", [tmp_path])
    msg = registry.resolve("demo_msgs/msg/C")
    assert isinstance(msg, MessageDef)
    assert [c.value for c in msg.constants] == ["with # hash", '"quoted"']
    assert registry.ros1_definition("demo_msgs/msg/C")[0] == 'string A=with # hash\nstring B="quoted"\n'


def test_ros2_naming_warnings(tmp_path: Path) -> None:
    write(tmp_path, "demo_msgs/msg/Mixed.msg", "int32 camelCase\nint32 lower_ok=1\n")
    diags = Diagnostics()
    TypeRegistry("ros2", [tmp_path], diags)
    assert [(d.code, d.severity, d.line) for d in diags] == [
        ("TY517", Severity.WARNING, 1),
        ("TY517", Severity.WARNING, 2),
    ]
    diags = Diagnostics()
    TypeRegistry("ros1", [tmp_path], diags)
    assert list(diags) == []


@pytest.mark.parametrize("distro", ["ros1", "ros2"])
def test_typestore_serialises_user_types(distro: str) -> None:
    registry = TypeRegistry(distro, [RB1_INTERFACES])  # type: ignore[arg-type]
    store = registry.typestore()
    assert store is registry.typestore()
    name = "procedures_msgs/srv/ProcedureQuery_Request"
    header_cls = store.types["procedures_msgs/msg/ProcedureHeader"]
    time_cls = store.types["builtin_interfaces/msg/Time"]
    request = store.types[name](header_cls(4, 0, time_cls(1, 2), "goto"))
    if distro == "ros1":
        raw = store.serialize_ros1(request, name)
        assert store.deserialize_ros1(raw, name) == request
        assert len(raw) == 4 + 4 + 8 + 4 + 4
    else:
        raw = store.serialize_cdr(request, name)
        assert store.deserialize_cdr(raw, name) == request
    # the shared per-process typestore is not modified
    assert "procedures_msgs/msg/ProcedureHeader" not in TypeRegistry(distro).typestore().fielddefs  # type: ignore[arg-type]


def test_unknown_distro() -> None:
    with pytest.raises(ValueError):
        TypeRegistry("ros3")  # type: ignore[arg-type]
