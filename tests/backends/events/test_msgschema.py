"""Strict message schemas (model/msgschema.py): closed objects, whole messages required where the robot sends
them, time as each ROS version names it, a TD's data schema laid over the ROS one only where it narrows,
ROS defaults filling what a partial value lacks."""

from __future__ import annotations

from typing import Any

from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

from td2adaptor.model.events import payload_schema
from td2adaptor.model.msgschema import default_of, fill, strictest, time_schema
from tests.runtime.rb1 import rb1_model

MARKERS = "ar_track_alvar_msgs/msg/AlvarMarkers"


def _valid(schema: Any, value: Any) -> bool:
    return bool(Draft202012Validator(schema).is_valid(value))


def test_time_is_named_as_each_ros_version_names_it() -> None:
    assert list(time_schema("ros1")["properties"]) == ["secs", "nsecs"]
    assert list(time_schema("ros2")["properties"]) == ["sec", "nanosec"]
    assert time_schema("ros1", complete=True)["required"] == ["secs", "nsecs"]
    assert time_schema("ros1", signed=True)["properties"]["secs"]["minimum"] == -(2**31)
    assert time_schema("ros1")["properties"]["secs"]["minimum"] == 0  # a ROS 1 time is unsigned
    assert time_schema("ros1", signed=True)["properties"]["nsecs"]["minimum"] == -(2**31)  # ROS 1 duration


def test_a_ros2_duration_has_unsigned_nanoseconds() -> None:
    """builtin_interfaces/Duration is `int32 sec` and `uint32 nanosec`: a schema allowing a negative nanosec
    would let a client send what the robot cannot take, and a scaffolded TD would warn about itself (XC611)."""
    from td2adaptor.model.msgschema import message_schema
    from td2adaptor.rostypes.registry import TypeRegistry

    table = TypeRegistry("ros2").table(["builtin_interfaces/msg/Duration", "builtin_interfaces/msg/Time"])
    for name in ("builtin_interfaces/msg/Duration", "builtin_interfaces/msg/Time"):
        props = message_schema(table.message(name), table)["properties"]
        assert props["nanosec"] == {"type": "integer", "minimum": 0, "maximum": 2**32 - 1}, name
        assert props["sec"] == {"type": "integer", "minimum": -(2**31), "maximum": 2**31 - 1}, name
    for distro, name in (("ros1", "secs"), ("ros2", "sec")):
        schema = payload_schema(rb1_model(), MARKERS, None, distro=distro, complete=True)
        stamp = schema["properties"]["header"]["properties"]["stamp"]
        assert name in stamp["properties"] and stamp["additionalProperties"] is False
    ros1 = payload_schema(rb1_model(), MARKERS, None, distro="ros1", complete=True)
    assert "seq" in ros1["properties"]["header"]["properties"]  # ROS 1's Header has one, ROS 2's none


def test_what_the_robot_sends_is_whole_what_a_client_sends_may_leave_fields_out() -> None:
    sent = payload_schema(rb1_model(), MARKERS, None, distro="ros2", complete=True)
    taken = payload_schema(rb1_model(), MARKERS, None, distro="ros2", complete=False)
    whole = fill(sent, {"markers": [{"id": 3}]})
    assert _valid(sent, whole) and not _valid(sent, {"markers": []})
    assert _valid(taken, {"markers": [{"id": 3}]}) and not _valid(taken, {"markers": [], "extra": 1})
    assert whole["markers"][0]["id"] == 3 and whole["header"]["stamp"] == {"sec": 0, "nanosec": 0}


def test_a_td_schema_narrows_but_never_widens() -> None:
    ros = {
        "type": "object",
        "properties": {
            "speed": {"type": "number"},
            "count": {"type": "integer", "minimum": 0, "maximum": 255},
            "stamp": time_schema("ros1"),
        },
        "additionalProperties": False,
    }
    td = {
        "title": "T",
        "required": ["speed", "sec"],
        "properties": {
            "speed": {"type": "number", "maximum": 2.0, "unit": "m/s"},
            "count": {"type": "integer", "minimum": -5, "maximum": 10},
            "stamp": {"type": "object", "properties": {"sec": {"type": "integer", "maximum": 9}}},
            "invented": {"type": "string"},
        },
        "additionalProperties": True,
    }
    out = strictest(ros, td)
    assert out["title"] == "T" and out["additionalProperties"] is False
    assert list(out["properties"]) == ["speed", "count", "stamp"]  # the message's members, not the TD's
    assert out["properties"]["speed"] == {"type": "number", "maximum": 2.0, "unit": "m/s"}
    assert (out["properties"]["count"]["minimum"], out["properties"]["count"]["maximum"]) == (0, 10)
    assert out["properties"]["stamp"]["properties"]["secs"]["maximum"] == 9  # the ROS 2 name matched
    assert out["required"] == ["speed"]
    assert strictest({}, {"type": "string"}) == {"type": "string"}  # nothing known of ROS: the TD's


def test_defaults_are_ros_defaults() -> None:
    schema = {
        "type": "object",
        "properties": {
            "a": {"type": "integer"},
            "b": {"type": "string"},
            "c": {"type": "boolean"},
            "d": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
            "e": {"type": "array", "items": {"type": "number"}},
        },
    }
    assert default_of(schema) == {"a": 0, "b": "", "c": False, "d": [0.0, 0.0, 0.0], "e": []}
    assert fill(schema, {"a": 5, "e": [1.0]}) == {"a": 5, "e": [1.0], "b": "", "c": False, "d": [0.0, 0.0, 0.0]}


def test_time_and_duration_ranges_are_the_type_sets_own() -> None:
    """ROS 2's Duration has a uint32 `nanosec` like Time (a negative one was let through to rclpy, whose C
    conversion then failed with Python's internal words); ROS 1's `duration` is two int32s."""
    from rosbags.typesys import Stores, get_typestore

    from td2adaptor.model.primitives import int_range

    store = get_typestore(Stores.ROS2_JAZZY)
    for name, signed in (("builtin_interfaces/msg/Time", False), ("builtin_interfaces/msg/Duration", True)):
        schema = time_schema("ros2", signed=signed)["properties"]
        for field, (_kind, (base, _)) in store.fielddefs[name][1]:
            lo, hi = int_range(base, "ros2") or (None, None)
            assert (schema[field]["minimum"], schema[field]["maximum"]) == (lo, hi), (name, field)
    assert not _valid(time_schema("ros2", signed=True), {"sec": 1, "nanosec": -1})
    assert _valid(time_schema("ros2", signed=True), {"sec": -1, "nanosec": 2**32 - 1})
    ros1_duration = time_schema("ros1", signed=True)["properties"]
    assert ros1_duration["nsecs"]["minimum"] == -(2**31) and ros1_duration["secs"]["minimum"] == -(2**31)
    assert time_schema("ros1")["properties"]["nsecs"]["minimum"] == 0
