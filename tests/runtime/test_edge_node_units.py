"""Units of the edge node that need no middleware: message conversion, the port's layout, error mapping,
the ROS 1 bridge's child environment."""

from __future__ import annotations

import array
import json
import os
import re
import sys
from typing import Any

from td2adaptor.model.events import ERROR_CODES
from td2adaptor.runtime import NoValue, PortCallFailed, PortTimeout, PortUnavailable
from td2adaptor.runtime.ros.bridge import child_environment
from td2adaptor.runtime.ros.genport import Layout, _port_error, to_plain
from td2adaptor.runtime.ros.words import INTERNAL, describe
from tests.conftest import REPO
from tests.runtime.rb1 import rb1_model


class Time:  # the shape of genpy.Time
    __slots__ = ["secs", "nsecs"]

    def __init__(self, secs: int, nsecs: int) -> None:
        self.secs, self.nsecs = secs, nsecs


class Header:  # the shape of a genpy message
    __slots__ = ["seq", "stamp", "frame_id"]

    def __init__(self) -> None:
        self.seq, self.stamp, self.frame_id = 7, Time(3, 4), "map"


def test_to_plain_gives_json_with_the_robots_own_field_names() -> None:
    value = to_plain({"h": Header(), "a": array.array("d", [1.0, float("nan")]), "b": b"\x01\x02", "t": (1, 2)})
    assert value == {
        "h": {"seq": 7, "stamp": {"secs": 3, "nsecs": 4}, "frame_id": "map"},  # a ROS 1 time, as ROS 1 names it
        "a": [1.0, None],  # NaN is no JSON number: null, and the rest of the message still goes out
        "b": [1, 2],
        "t": [1, 2],
    }
    assert to_plain(float("inf")) is None and to_plain(True) is True and to_plain(3) == 3
    json.dumps(value, allow_nan=False)


def test_to_plain_gives_sequences_of_numbers_as_lists_with_no_number_that_is_not_finite() -> None:
    """The sequences' fast paths (integers or texts as they are, floats checked) give what the general one does."""
    inf, nan = float("inf"), float("nan")
    assert to_plain(array.array("i", range(5))) == [0, 1, 2, 3, 4]
    assert to_plain([True, None, "a", 2**70]) == [True, None, "a", 2**70]
    assert to_plain((0.5, inf, -inf, nan)) == [0.5, None, None, None]
    assert to_plain([1, 2.5, inf, "a", None, [nan, 1.0], (Header(),)]) == [
        1,
        2.5,
        None,
        "a",
        None,
        [None, 1.0],
        [{"seq": 7, "stamp": {"secs": 3, "nsecs": 4}, "frame_id": "map"}],
    ]
    copy = [1, 2]
    assert to_plain(copy) is not copy  # a new list: the message's own is never handed on


class Stamp:  # the shape of a rosidl message: its field names from get_fields_and_field_types
    def __init__(self) -> None:
        self.sec, self.nanosec = 5, 6

    @staticmethod
    def get_fields_and_field_types() -> dict[str, str]:
        return {"sec": "int32", "nanosec": "uint32"}


class Answer:
    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)

    @staticmethod
    def get_fields_and_field_types() -> dict[str, str]:
        return {n: "" for n in ("stamp", "state", "ratio", "flag", "none", "raw", "ids", "chars", "xs", "nested")}


def test_to_plain_gives_the_same_for_a_message_type_it_met_before() -> None:
    """The exact-type fast paths (a message type met before, its scalar fields taken as they are, integer
    arrays) give what the general checks give the first time, every time."""

    def answer(ratio: float) -> Answer:
        return Answer(
            stamp=Stamp(),
            state="running",
            ratio=ratio,
            flag=True,
            none=None,
            raw=b"\x07",
            ids=array.array("q", [1, -2]),
            chars=array.array("u", "ab"),
            xs=array.array("f", [0.5, float("inf")]),
            nested=[Stamp(), {"k": float("nan")}],
        )

    expected = {
        "stamp": {"sec": 5, "nanosec": 6},
        "state": "running",
        "ratio": None,
        "flag": True,
        "none": None,
        "raw": [7],
        "ids": [1, -2],
        "chars": ["a", "b"],
        "xs": [0.5, None],
        "nested": [{"sec": 5, "nanosec": 6}, {"k": None}],
    }
    first = to_plain(answer(float("nan")))
    assert first == expected and to_plain(answer(float("nan"))) == expected
    assert to_plain(answer(2.5))["ratio"] == 2.5
    assert [type(v) for v in to_plain(answer(1.0))["ids"]] == [int, int]
    json.dumps(first, allow_nan=False)
    header = {"seq": 7, "stamp": {"secs": 3, "nsecs": 4}, "frame_id": "map"}
    assert to_plain(Header()) == to_plain(Header()) == header  # a genpy message type met before


def test_layout_of_the_rb1_and_its_json_round_trip() -> None:
    layout = Layout.of(rb1_model())
    assert layout.components[:3] == ("GoToComponent", "PickComponent", "PlaceComponent")
    assert layout.runs == {("GoToComponent", "gotoRun"), ("PickComponent", "pickRun"), ("PlaceComponent", "placeRun")}
    # the queries and cancels whose requests carry the mission id (the model's Procedure.slot, not a guess from
    # the generated method's signature)
    assert layout.ids == {(c, a.replace("Run", role)) for c, a in layout.runs for role in ("Query", "Cancel")}
    assert Layout.from_json(json.loads(json.dumps(layout.to_json()))) == layout


def test_generated_errors_map_onto_port_errors_by_name() -> None:
    def error(name: str, **attrs: Any) -> Exception:
        exc: Exception = type(name, (Exception,), {})("what happened")
        for key, value in attrs.items():
            setattr(exc, key, value)
        return exc

    assert isinstance(_port_error(error("ServiceUnavailable")), PortUnavailable)
    assert isinstance(_port_error(error("CallTimeout")), PortTimeout)
    assert isinstance(_port_error(error("NoMessage")), NoValue)
    failed = _port_error(error("CallFailed", response={"result": {"result": "error"}}))
    assert isinstance(failed, PortCallFailed) and failed.response == {"result": {"result": "error"}}
    assert str(failed) == "what happened"


def test_failures_are_told_in_user_words_never_class_names() -> None:
    silent = type("CallTimeout", (Exception,), {})()  # a generated error without a message
    assert describe(_port_error(silent)) == "the robot did not answer in time"
    assert describe(PortUnavailable("service gotoRun is gone")) == "the robot is not reachable: service gotoRun is gone"
    assert describe(PortCallFailed("refused")) == "the robot call failed: refused"
    assert describe(NoValue()) == "the robot has published no value yet"
    # the request could not be built (a field the message type refuses): the robot never saw it
    assert describe(TypeError("bad field")) == "the edge node could not make the robot call: bad field"
    assert describe(RuntimeError("a bug")) == INTERNAL  # the details go to the log, not to users
    for exc in (silent, PortUnavailable(), PortTimeout(), PortCallFailed(), NoValue(), KeyError("k")):
        text = describe(_port_error(exc) if exc is silent else exc)
        assert "Port" not in text and "Error" not in text and "Timeout" not in text, text


def test_every_error_code_is_documented_in_order() -> None:
    """Error codes are for programs to branch on: docs/wot.md says what each means and what to do."""
    text = (REPO / "docs" / "wot.md").read_text(encoding="utf-8")
    codes = re.findall(r"^\| `([a-z-]+)` \| ", text, re.MULTILINE)
    assert codes[0] == "code" and codes[1:] == list(ERROR_CODES)  # the header, then one row per code


def test_the_ros1_bridge_child_gets_no_ros2_and_none_of_our_site_packages() -> None:
    venv_site = os.path.join(sys.prefix, "lib", "site-packages")
    environ = {
        "PATH": "/usr/bin",
        "ROS_DOMAIN_ID": "42",
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
        "_ROS_WHEELS_BOOTSTRAP_COMPLETE": "1",
        "LD_LIBRARY_PATH": os.pathsep.join([os.path.join(sys.prefix, "lib"), "/opt/ros/noetic/lib"]),
        "PYTHONPATH": os.pathsep.join([venv_site, "/opt/ros/noetic/lib/python3/dist-packages"]),
        "ROS_HOSTNAME": "127.0.0.1",
        "ROS_MASTER_URI": "http://127.0.0.1:11311",
    }
    env = child_environment(environ, ["/tmp/shim", "/tmp/pkg"], "http://127.0.0.1:12345")
    assert env["PYTHONPATH"].split(os.pathsep) == ["/tmp/shim", "/tmp/pkg", "/opt/ros/noetic/lib/python3/dist-packages"]
    assert env["LD_LIBRARY_PATH"] == "/opt/ros/noetic/lib"
    assert env["ROS_MASTER_URI"] == "http://127.0.0.1:12345" and env["ROS_HOSTNAME"] == "127.0.0.1"
    assert not {"ROS_DOMAIN_ID", "RMW_IMPLEMENTATION", "_ROS_WHEELS_BOOTSTRAP_COMPLETE"} & set(env)
