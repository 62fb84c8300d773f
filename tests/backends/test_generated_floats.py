"""The float checks of the generated rclpy and rospy packages (issue 30, item 1): `construct_*` refuses a float
that is not finite, or beyond the float32 range in a float32 field (it would reach the robot as infinity), with
a ValueError naming the field: a keyword argument, an array's item, a field of a message given as a mapping.
What a float32 holds is built, FLT_MAX too (rosidl's own check refuses FLT_MAX as a double: it is passed on as
C's float.h literal, the same float32).

No mocks: rclpy's Jazzy message classes in this process; Debian's genpy messages under the system Python
(tests/ros1/harness.py) for rospy.
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

PACKAGE = "float_checks_bot_adaptor"


TD = values_td(
    "float-checks",
    {
        "level": "std_msgs/msg/Float32",
        "samples": "std_msgs/msg/Float32MultiArray",
        "wide": "std_msgs/msg/Float64MultiArray",
        "twist": "geometry_msgs/msg/Twist",
    },
)

#: run with `component` (a ValuesComponent) in scope, in either interpreter; prints what held as JSON
CHECKS = """
import json, struct
FLT_MAX = 3.4028234663852886e38

def refused(call, *words):
    try:
        call()
    except ValueError as exc:
        return all(word in str(exc) for word in words) or str(exc)
    except Exception as exc:
        return type(exc).__name__ + ": " + str(exc)
    return "built"

def as_float32(value):
    return struct.unpack("<f", struct.pack("<f", value))[0]

c = component
held = {
    "float32 3.5e38": refused(lambda: c.construct_level_Msg(data=3.5e38), "data", "float32", "3.5e+38"),
    "float32 -inf": refused(lambda: c.construct_level_Msg(data=float("-inf")), "data", "finite"),
    "float32 nan": refused(lambda: c.construct_level_Msg(data=float("nan")), "data", "finite"),
    "float32[] item": refused(lambda: c.construct_samples_Msg(data=[1.0, -3.5e38]), "data", "float32"),
    "float64[] item": refused(lambda: c.construct_wide_Msg(data=[1e308, float("inf")]), "data", "finite"),
    "float64[] huge int": refused(lambda: c.construct_wide_Msg(data=[10**400]), "data", "finite"),
    "nested mapping": refused(lambda: c.construct_twist_Msg(linear={"x": float("-inf")}), "Vector3", ".x"),
    "text": refused(lambda: c.construct_level_Msg(data="1.5")) == "TypeError: data must be a number, not str",
}
level = c.construct_level_Msg(data=FLT_MAX)
held["FLT_MAX built"] = as_float32(level.data) == FLT_MAX
samples = c.construct_samples_Msg(data=[-FLT_MAX, -1.5, 2])
held["float32[] built"] = [as_float32(v) for v in samples.data] == [-FLT_MAX, -1.5, 2.0]
twist = c.construct_twist_Msg(linear={"x": 1e308}, angular={"z": -2})
held["nested built"] = (twist.linear.x, twist.angular.z) == (1e308, -2.0)
print(json.dumps(held))
"""


def check(held: dict[str, Any]) -> None:
    assert held == dict.fromkeys(held, True), {k: v for k, v in held.items() if v is not True}
    assert len(held) == 11


def test_rclpy_construct_refuses_floats_ros_2_cannot_hold(ros2_domain: int, tmp_path: Path, capsys: Any) -> None:
    import rclpy
    from rclpy.context import Context

    path = tmp_path / "td.json"
    path.write_text(json.dumps(TD), encoding="utf-8")
    _, package = build_rclpy(path, tmp_path / "src")
    sys.path.insert(0, str(package))
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("float_checks", context=context)
    try:
        module = importlib.import_module(PACKAGE)
        scope = {"component": module.ValuesComponent(node, "checks")}
        exec(CHECKS, scope)  # noqa: S102 - the test's own code, the same run under ROS 1 below
        check(json.loads(capsys.readouterr().out.splitlines()[-1]))
    finally:
        sys.path.remove(str(package))
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_rospy_construct_refuses_floats_ros_1_cannot_hold(tmp_path: Path) -> None:
    require_ok(harness.ros1_problem())
    path = tmp_path / "td.json"
    path.write_text(json.dumps(TD), encoding="utf-8")
    generated.generate("rospy", path, tmp_path)
    code = f"from {PACKAGE} import ValuesComponent\ncomponent = ValuesComponent('checks')\n" + CHECKS
    environ = dict(os.environ, PYTHONPATH=str(tmp_path / PACKAGE / "src"))
    out = subprocess.run([harness.SYSTEM_PYTHON, "-c", code], env=environ, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    check(json.loads(out.stdout.splitlines()[-1]))
