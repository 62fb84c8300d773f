"""`publish_P_Msg(msg)` of a message built by hand (issue 30, item 1): construct_* checks the values it is given,
but a message a caller built or changed itself went out as it was: `Float32(data=inf)`, 300 in a uint8 (rclpy
carries it as 44), a nanosec of 2**33. The generated publishers of both ROS versions now walk the message by its
own field types (rosidl's get_fields_and_field_types(), genpy's _slot_types) and refuse such a message with a
ValueError naming the field, before anything is sent; what the types hold is published as before.

No mocks: rclpy's Jazzy message classes and a real publisher in this process; Debian's genpy messages under the
system Python (tests/ros1/harness.py) for rospy, where a message that passes the check reaches rospy (which
then says no node is running: this test starts none).
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from tests import generated
from tests.backends.values_td import values_td
from tests.ros1 import harness
from tests.ros2.common import build_rclpy
from tests.tools import require_ok

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

PACKAGE = "publish_checks_bot_adaptor"


TD = values_td(
    "publish-checks",
    {
        "level": "std_msgs/msg/Float32",
        "samples": "std_msgs/msg/Float32MultiArray",
        "wide": "std_msgs/msg/Float64MultiArray",
        "twist": "geometry_msgs/msg/Twist",
        "small": "std_msgs/msg/UInt8",
        "bytes": "std_msgs/msg/UInt8MultiArray",
        "stamped": "geometry_msgs/msg/PointStamped",
    },
)

#: run with `component` (a ValuesComponent) in scope, in either interpreter; prints what happened to each
#: publish as JSON: "sent" when nothing was raised, else the exception's class and words
CHECKS = """
import json

def outcome(call):
    try:
        call()
    except Exception as exc:
        return type(exc).__name__ + ": " + str(exc)
    return "sent"

c = component

def hand(name, **fields):
    msg = getattr(c, "construct_" + name + "_Msg")()
    for key, value in fields.items():
        setattr(msg, key, value)
    return msg

twist = hand("twist")
twist.angular.z = float("nan")
stamped = hand("stamped")
stamp = stamped.header.stamp
setattr(stamp, "nanosec" if hasattr(stamp, "nanosec") else "nsecs", 2**33)  # ROS 2's Time, ROS 1's
deep = hand("samples", data=[0.5])
deep.layout.data_offset = -1
found = {
    "level inf": outcome(lambda: c.publish_level_Msg(hand("level", data=float("inf")))),
    "level 3.5e38": outcome(lambda: c.publish_level_Msg(hand("level", data=3.5e38))),
    "samples nan": outcome(lambda: c.publish_samples_Msg(hand("samples", data=[1.0, float("nan")]))),
    "wide inf": outcome(lambda: c.publish_wide_Msg(hand("wide", data=[1e308, 2.0, float("-inf")]))),
    "twist nested nan": outcome(lambda: c.publish_twist_Msg(twist)),
    "small 300": outcome(lambda: c.publish_small_Msg(hand("small", data=300))),
    "stamp 2**33": outcome(lambda: c.publish_stamped_Msg(stamped)),
    "layout -1": outcome(lambda: c.publish_samples_Msg(deep)),
    "level ok": outcome(lambda: c.publish_level_Msg(hand("level", data=-3.0e38))),
    "wide ok": outcome(lambda: c.publish_wide_Msg(hand("wide", data=[1e308, -1e-300]))),
    "bytes ok": outcome(lambda: c.publish_bytes_Msg(hand("bytes", data=bytes(range(256))))),
    "small ok": outcome(lambda: c.publish_small_Msg(hand("small", data=255))),
}
print(json.dumps(found))
"""

#: what each refused publish must say: the exception and the words naming the field and the limit
REFUSED = {
    "level inf": ("ValueError", "Float32.data", "finite float32", "inf"),
    "level 3.5e38": ("ValueError", "Float32.data", "float32", "3.5e+38"),
    "samples nan": ("ValueError", "Float32MultiArray.data[1]", "nan"),
    "wide inf": ("ValueError", "Float64MultiArray.data[2]", "-inf"),
    "twist nested nan": ("ValueError", "Twist.angular.z", "nan"),
    "small 300": ("ValueError", "UInt8.data", "0..255", "300"),
    "stamp 2**33": ("ValueError", "PointStamped.header.stamp.", "uint32", "8589934592"),
    "layout -1": ("ValueError", "Float32MultiArray.layout.data_offset", "uint32", "-1"),
}


def check(found: dict[str, str], passed: str) -> None:
    """Every refusal a ValueError naming the field; every message the types hold reaches `passed`."""
    wrong = {}
    for case, words in REFUSED.items():
        said = found.pop(case)
        if not said.startswith(words[0] + ": ") or not all(word in said for word in words[1:]):
            wrong[case] = said
    for case, said in found.items():
        if not said.startswith(passed):
            wrong[case] = said
    assert not wrong, wrong
    assert len(found) == 4


def test_rclpy_publish_refuses_a_hand_built_message_ros_2_cannot_hold(
    ros2_domain: int, tmp_path: Path, capsys: Any
) -> None:
    import rclpy
    from rclpy.context import Context

    path = tmp_path / "td.json"
    path.write_text(json.dumps(TD), encoding="utf-8")
    _, package = build_rclpy(path, tmp_path / "src")
    sys.path.insert(0, str(package))
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("publish_checks", context=context)
    try:
        module = importlib.import_module(PACKAGE)
        scope = {"component": module.ValuesComponent(node, "checks")}
        exec(CHECKS, scope)  # noqa: S102 - the test's own code, the same run under ROS 1 below
        check(json.loads(capsys.readouterr().out.splitlines()[-1]), "sent")
    finally:
        sys.path.remove(str(package))
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_rospy_publish_refuses_a_hand_built_message_ros_1_cannot_hold(tmp_path: Path) -> None:
    require_ok(harness.ros1_problem())
    path = tmp_path / "td.json"
    path.write_text(json.dumps(TD), encoding="utf-8")
    generated.generate("rospy", path, tmp_path)
    code = f"from {PACKAGE} import ValuesComponent\ncomponent = ValuesComponent('checks')\n" + CHECKS
    environ = dict(os.environ, PYTHONPATH=str(tmp_path / PACKAGE / "src"))
    out = subprocess.run([harness.SYSTEM_PYTHON, "-c", code], env=environ, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    # the check passed and the message went on to rospy, which has no node to publish from in this test
    check(json.loads(out.stdout.splitlines()[-1]), "NotInitialized")
