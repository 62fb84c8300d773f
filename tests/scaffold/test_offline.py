"""`td2adaptor scaffold` from what needs no running robot: a listing with interface folders, bags written
here with rosbags' writers from real messages, `--merge`, and bad input (diagnostics, never a traceback)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from tests.conftest import EXAMPLE, REPO
from tests.scaffold.common import (
    INTERFACES,
    compare_with_example,
    compiled_errors,
    example_td,
    scaffold,
    w3c_errors,
)

NAV = "/rb1_base_a/robot_local_control/NavigationComponent"
RB1_LISTING = """\
title: Robotnik RB-1
publishes:
  /rb1_base_a/robot_local_control/state: robot_local_control_msgs/Status
  /rb1_base_a/ar_pose_marker: ar_track_alvar_msgs/msg/AlvarMarkers
subscribes:
  /door1/door_controller/command: {type: std_msgs/Float64, latch: true, qos: {durability: transient_local, depth: 1}}
services:
""" + "".join(
    f"  {NAV}/{c}Component/{leaf}: {srv}\n"
    for c in ("GoTo", "Pick", "Place")
    for leaf, srv in (
        ("add", f"robot_local_control_msgs/{c}Petition"),
        ("cancel", "procedures_msgs/ProcedureQuery"),
        ("query_state", "procedures_msgs/ProcedureQuery"),
    )
)


def test_a_listing_with_the_interface_folders_gives_the_rb1_td(tmp_path: Path) -> None:
    listing = tmp_path / "rb1.yaml"
    listing.write_text(RB1_LISTING, encoding="utf-8")
    done = scaffold([str(listing), "-I", str(INTERFACES)], tmp_path / "td.json")
    assert done.code == 0, done.stderr
    assert done.doc is not None
    assert done.doc["title"] == "Robotnik RB-1" and done.doc["@type"] == "Thing"
    assert "SCF105" in done.stderr  # the robot namespace it chose, said
    compare_with_example(done.doc, example_td(), "ros2")
    # the listing says what the graph cannot: the door's depth, so the binding is the example's exactly
    assert done.doc["properties"]["command"]["forms"][0] == example_td()["properties"]["door"]["forms"][0]
    assert compiled_errors(done.doc, tmp_path) == []
    assert w3c_errors(done.doc) == []


def test_merge_into_the_example_gives_the_example_back(tmp_path: Path) -> None:
    listing = tmp_path / "rb1.yaml"
    listing.write_text(RB1_LISTING, encoding="utf-8")
    done = scaffold([str(listing), "-I", str(INTERFACES), "--merge", str(EXAMPLE / "td.json")], tmp_path / "td.json")
    assert done.code == 0, done.stderr
    assert done.doc == example_td()  # hand-written names, titles, descriptions, components: all kept


def test_merge_keeps_annotations_updates_the_binding_and_adds_what_is_new(tmp_path: Path) -> None:
    example = example_td()
    example["@type"] = ["Thing", "saref:Device"]
    example["@context"].append({"saref": "https://saref.etsi.org/core/"})
    state = example["properties"]["availability"]
    state["@type"] = "saref:State"
    state["properties"]["robot_id"]["description"] = "the robot's name"
    state["forms"][0]["rosv:type"] = "robot_local_control_msgs/msg/OldStatus"  # outdated: the source wins
    state["forms"].append({"href": "mqtt://broker/state", "op": "readproperty"})  # a form of the user's
    del example["actions"]["pickCancel"]  # new in the source: added
    example["properties"]["battery"] = {  # not in the source: kept (SCF109)
        "type": "number",
        "forms": [{"href": "ros:battery", "rosv:name": "/{{robotName}}/battery", "rosv:type": "std_msgs/msg/Float32"}],
    }
    existing = tmp_path / "existing.json"
    existing.write_text(json.dumps(example), encoding="utf-8")
    listing = tmp_path / "rb1.yaml"
    listing.write_text(RB1_LISTING, encoding="utf-8")
    done = scaffold([str(listing), "-I", str(INTERFACES), "--merge", str(existing)], tmp_path / "td.json")
    assert done.code == 0, done.stderr
    doc = done.doc
    assert doc is not None
    assert "SCF109" in done.stderr and "battery" in done.stderr
    assert doc["@type"] == ["Thing", "saref:Device"] and doc["@context"] == example["@context"]
    merged = doc["properties"]["availability"]
    assert merged["@type"] == "saref:State" and merged["title"] == "Availability"
    assert merged["properties"]["robot_id"]["description"] == "the robot's name"
    assert merged["forms"][0]["rosv:type"] == "robot_local_control_msgs/msg/Status"
    assert merged["forms"][1] == {"href": "mqtt://broker/state", "op": "readproperty"}
    assert doc["properties"]["battery"] == example["properties"]["battery"]
    assert doc["actions"]["pickCancel"]["forms"][0]["rosv:name"].endswith("/PickComponent/cancel")
    assert doc["actions"]["pickRun"]["rosv:procedure"]["cancel"] == "pickCancel"
    assert compiled_errors(doc, tmp_path) == []


def test_merge_keeps_the_hand_written_constraints_the_ros_types_allow_and_says_what_it_dropped(
    tmp_path: Path,
) -> None:
    example = example_td()
    goals = example["actions"]["gotoRun"]["input"]["properties"]["procedure"]["properties"]["goals"]
    goals["maxItems"] = 8  # an unbounded sequence: the person's limit stays
    pose = goals["items"]["properties"]["pose"]
    pose["properties"]["x"].update(minimum=-50, maximum=50)  # float64: any range is the person's
    pose["required"] = ["x", "y", "z"]  # z is no field of the message: that name goes
    state = example["properties"]["availability"]["properties"]
    stamp = state["localization_status"]["properties"]["pose"]["properties"]["header"]["properties"]["stamp"]
    stamp["properties"]["nanosec"]["minimum"] = -1  # below a uint32's 0: dropped
    stamp["properties"]["nanosec"]["maximum"] = 999_999_999  # narrower than the uint32: kept
    stamp["properties"]["sec"]["maximum"] = 2**40  # above an int32's maximum: dropped
    state["robot_id"].update(maxLength=64, pattern="^rb1_", minimum=3)  # a string has no minimum
    example["properties"]["door"]["properties"]["data"].update(minimum=0, maximum=1)
    existing = tmp_path / "existing.json"
    existing.write_text(json.dumps(example), encoding="utf-8")
    listing = tmp_path / "rb1.yaml"
    listing.write_text(RB1_LISTING, encoding="utf-8")
    done = scaffold([str(listing), "-I", str(INTERFACES), "--merge", str(existing)], tmp_path / "td.json")
    assert done.code == 0, done.stderr
    doc = done.doc
    assert doc is not None
    # what the ROS types allow is kept: the merged TD is the edited one but for what they contradict
    expected = json.loads(json.dumps(example))
    exp_stamp = expected["properties"]["availability"]["properties"]["localization_status"]["properties"]["pose"]
    exp_stamp = exp_stamp["properties"]["header"]["properties"]["stamp"]["properties"]
    exp_stamp["nanosec"]["minimum"] = 0
    exp_stamp["sec"]["maximum"] = 2**31 - 1
    del expected["properties"]["availability"]["properties"]["robot_id"]["minimum"]
    exp_goals = expected["actions"]["gotoRun"]["input"]["properties"]["procedure"]["properties"]["goals"]
    exp_goals["items"]["properties"]["pose"]["required"] = ["x", "y"]
    assert doc == expected
    assert compiled_errors(doc, tmp_path) == []
    # and said: each dropped one with the reason, one line naming the kept ones
    at = "/properties/availability/properties/localization_status/properties/pose/properties/header/properties"
    assert (
        "warning SCF114: hand-written minimum -1 dropped: below the minimum of uint32 (0..4294967295) "
        f"at {at}/stamp/properties/nanosec/minimum"
    ) in done.stderr, done.stderr
    assert (
        f"hand-written maximum {2**40} dropped: above the maximum of int32 (-2147483648..2147483647)"
    ) in done.stderr
    assert "hand-written minimum 3 dropped: the field is a string at /properties/availability/properties/robot_id/" in (
        done.stderr
    )
    assert 'hand-written required "z" dropped: the message has no field z' in done.stderr
    kept = next(line for line in done.stderr.splitlines() if "SCF113" in line)
    assert "kept 9 hand-written constraints the ROS types allow (4 dropped)" in kept, kept
    for pointer in (
        "/actions/gotoRun/input/properties/procedure/properties/goals/maxItems",
        "/properties/door/properties/data/maximum",
        "/properties/availability/properties/robot_id/pattern",
    ):
        assert pointer in kept


def test_a_merge_with_nothing_hand_written_says_nothing_about_constraints(tmp_path: Path) -> None:
    listing = tmp_path / "rb1.yaml"
    listing.write_text(RB1_LISTING, encoding="utf-8")
    done = scaffold([str(listing), "-I", str(INTERFACES), "--merge", str(EXAMPLE / "td.json")], tmp_path / "td.json")
    assert done.code == 0 and "SCF113" not in done.stderr and "SCF114" not in done.stderr, done.stderr


# ---------------------------------------------------------------------------------------------------------
# bags


def _status(store: Any, robot: str) -> Any:
    """A real robot_local_control_msgs/Status, every nested message built from the typestore's classes."""

    def build(name: str) -> Any:
        cls = store.types[name]
        fields = store.fielddefs[name][1]
        values = {}
        for fname, desc in fields:
            values[fname] = _default(store, desc, build)
        return cls(**values)

    msg = build("robot_local_control_msgs/msg/Status")
    msg.robot_id = robot
    return msg


def _default(store: Any, desc: Any, build: Any) -> Any:
    import numpy as np

    kind, detail = desc[0], desc[1]
    if kind == 1:  # base type
        base = detail[0]
        return "" if base == "string" else False if base == "bool" else 0.0 if base.startswith("float") else 0
    if kind == 2:  # message
        return build(detail)
    if kind in (3, 4):  # array / sequence of something
        inner = detail[0]
        if inner[0] == 1 and inner[1][0] != "string":
            return np.zeros(detail[1] if kind == 3 else 0, dtype=np.float64)
        return [] if kind == 4 else [_default(store, inner, build) for _ in range(detail[1])]
    raise AssertionError(desc)


def _write_bag(tmp: Path, kind: str) -> Path:
    """A bag of `kind` (ros1: .bag; ros2: a db3 bag folder; mcap: the .mcap file of a bag folder)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    from td2adaptor.rostypes.registry import TypeRegistry

    ros1 = TypeRegistry("ros1", [INTERFACES]).typestore()
    ros2 = TypeRegistry("ros2", [INTERFACES]).typestore()
    if kind == "ros1":
        return _write_bag1(tmp, ros1, Writer1)
    bag2 = tmp / "rb1_ros2"
    plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
    zero = QosTime(0, 0)
    latched = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, zero, zero,
                  QosLiveliness.AUTOMATIC, zero, False)  # fmt: skip
    with Writer2(bag2, version=9, storage_plugin=plugin) as writer:
        conn = writer.add_connection("/rb1_bag/robot_local_control/state", "robot_local_control_msgs/msg/Status",
                                     typestore=ros2)  # fmt: skip
        door = writer.add_connection("/rb1_bag/door_state", "std_msgs/msg/Float64", typestore=ros2,
                                     offered_qos_profiles=[latched])  # fmt: skip
        writer.write(conn, 1, ros2.serialize_cdr(_status(ros2, "rb1_bag"), "robot_local_control_msgs/msg/Status"))
        writer.write(door, 2, ros2.serialize_cdr(ros2.types["std_msgs/msg/Float64"](data=0.5), "std_msgs/msg/Float64"))
    if kind == "mcap":
        (found,) = bag2.glob("*.mcap")
        return found
    return bag2


def _write_bag1(tmp: Path, ros1: Any, writer_class: Any) -> Path:
    bag1 = tmp / "rb1.bag"
    with writer_class(bag1) as writer:
        conn = writer.add_connection("/rb1_bag/robot_local_control/state", "robot_local_control_msgs/msg/Status",
                                     typestore=ros1)  # fmt: skip
        door = writer.add_connection("/rb1_bag/door_state", "std_msgs/msg/Float64", typestore=ros1, latching=1)
        writer.write(conn, 1, ros1.serialize_ros1(_status(ros1, "rb1_bag"), "robot_local_control_msgs/msg/Status"))
        float64 = ros1.types["std_msgs/msg/Float64"]
        writer.write(door, 2, ros1.serialize_ros1(float64(data=0.5), "std_msgs/msg/Float64"))
    return bag1


@pytest.mark.parametrize("kind", ["ros1", "ros2", "mcap"])
def test_a_bag_gives_read_properties_with_the_message_schemas(kind: str, tmp_path: Path) -> None:
    bag = _write_bag(tmp_path, kind)
    # no --interfaces: the custom types' definitions come from the bag itself
    done = scaffold([str(bag)], tmp_path / "td.json")
    assert done.code == 0, done.stderr
    assert "SCF103" not in done.stderr and "(0 errors, 0 warnings)" in done.stderr, done.stderr
    doc = done.doc
    assert doc is not None
    assert sorted(doc["properties"]) == ["doorState", "state"]
    state = doc["properties"]["state"]
    assert state["forms"][0]["rosv:name"] == "/{{robotName}}/robot_local_control/state"
    assert state["forms"][0]["rosv:type"] == "robot_local_control_msgs/msg/Status"
    example = example_td()["properties"]["availability"]
    # ROS 1 or ROS 2 bag: the TD's schema is the ROS 2 spelling (sec/nanosec), as the example's
    assert {k: state[k] for k in ("type", "properties")}["properties"].keys() == example["properties"].keys()
    stamp = state["properties"]["robot_status"]["properties"]["pose"]["properties"]["header"]["properties"]["stamp"]
    assert set(stamp["properties"]) == {"sec", "nanosec"}
    # the latched / transient-local topic keeps that durability
    assert doc["properties"]["doorState"]["forms"][0]["rosv:qos"]["durability"] == "transient_local"
    assert compiled_errors(doc, tmp_path) == []
    assert w3c_errors(doc) == []


# ---------------------------------------------------------------------------------------------------------
# bad input: a located diagnostic with its code, exit 1, never a traceback


def _expect(args: list[str], code: str, tmp: Path) -> str:
    done = scaffold(args, tmp / "out.json", timeout=60)
    assert done.code == 1 and code in done.stderr, done.stderr
    assert not (tmp / "out.json").exists()
    return done.stderr


def test_bad_input_is_a_diagnostic(tmp_path: Path) -> None:
    _expect([str(tmp_path / "nothing.bag")], "SCF100", tmp_path)
    (tmp_path / "broken.bag").write_bytes(b"#ROSBAG V2.0\nnot a bag at all")
    _expect([str(tmp_path / "broken.bag")], "SCF100", tmp_path)
    (tmp_path / "bad.yaml").write_text("publishes: [unclosed", encoding="utf-8")
    _expect([str(tmp_path / "bad.yaml")], "SCF100", tmp_path)
    (tmp_path / "keys.yaml").write_text("topics: {}\n", encoding="utf-8")
    _expect([str(tmp_path / "keys.yaml")], "SCF100", tmp_path)
    (tmp_path / "entry.yaml").write_text("publishes:\n  relative/name: std_msgs/Float64\n", encoding="utf-8")
    _expect([str(tmp_path / "entry.yaml")], "SCF111", tmp_path)
    (tmp_path / "type.yaml").write_text("services:\n  /a/b: not a type\n", encoding="utf-8")
    _expect([str(tmp_path / "type.yaml")], "SCF111", tmp_path)
    good = tmp_path / "good.yaml"
    good.write_text("publishes:\n  /a/b: std_msgs/Float64\n", encoding="utf-8")
    _expect([str(good), "--include", "("], "SCF108", tmp_path)
    _expect([str(good), "--namespace", "/elsewhere"], "SCF102", tmp_path)
    _expect([str(good), "--merge", str(tmp_path / "missing.json")], "SCF110", tmp_path)
    (tmp_path / "notd.json").write_text("[1, 2]", encoding="utf-8")
    _expect([str(good), "--merge", str(tmp_path / "notd.json")], "SCF110", tmp_path)
    # a port nobody listens on: no master
    stderr = _expect(["ros1", "--master-uri", "http://127.0.0.1:9/", "--wait", "2"], "SCF101", tmp_path)
    assert "ros1: error SCF101" in stderr, stderr


def test_an_unknown_type_leaves_the_affordance_without_a_schema_and_says_why(tmp_path: Path) -> None:
    listing = tmp_path / "robot.yaml"
    listing.write_text("publishes:\n  /robot/odd: odd_msgs/msg/Odd\n  /robot/ok: std_msgs/msg/Bool\n", encoding="utf-8")
    done = scaffold([str(listing)], tmp_path / "td.json")
    assert done.code == 0 and "SCF103" in done.stderr and "--interfaces" in done.stderr, done.stderr
    # located at the listing, not at <input>
    assert f"{listing}: warning SCF103" in done.stderr and "<input>" not in done.stderr, done.stderr
    assert done.doc is not None and "properties" not in done.doc["properties"]["odd"]
    assert done.doc["properties"]["ok"]["properties"] == {"data": {"type": "boolean"}}


def test_the_command_is_documented() -> None:
    text = (REPO / "docs" / "scaffold.md").read_text(encoding="utf-8")
    for code in ("SCF100", "SCF103", "SCF104", "SCF109"):
        assert code in text
    assert "td2adaptor scaffold" in (REPO / "README.md").read_text(encoding="utf-8")


def test_a_scaffolded_time_and_duration_agree_with_the_validator(tmp_path: Path) -> None:
    """A new user's conveyor: the scaffold wrote a ROS 2 Duration's `nanosec` as an int32 and `validate` then
    warned (XC611) that the TD it had just written contradicts the type (uint32). Both now read the type."""
    package = tmp_path / "ifs" / "belt_msgs" / "msg"
    package.mkdir(parents=True)
    (package / "Timing.msg").write_text("duration max_wait\ntime stamp\n", encoding="utf-8")
    listing = tmp_path / "belt.yaml"
    listing.write_text("publishes:\n  /belt1/timing: belt_msgs/msg/Timing\n  /belt1/on: std_msgs/Bool\n", "utf-8")
    done = scaffold([str(listing), "-I", str(tmp_path / "ifs")], tmp_path / "td.json")
    assert done.code == 0, done.stderr
    assert done.doc is not None
    nanosec = done.doc["properties"]["timing"]["properties"]["max_wait"]["properties"]["nanosec"]
    assert (nanosec["minimum"], nanosec["maximum"]) == (0, 2**32 - 1)
    path = tmp_path / "check.td.json"
    path.write_text(json.dumps(done.doc), encoding="utf-8")
    result = td2adaptor.compile(path, interfaces=[tmp_path / "ifs"])
    assert [d.code for d in result.diagnostics if d.code.startswith("XC")] == []
