"""The integer checks of the generated rclpy package (found in the new-user run with a conveyor): Jazzy's rosidl
messages check a field only with ROS_PYTHON_CHECK_FIELDS=1, so `construct_*` passed 300 for a uint8 on, and the
robot received 44 (a negative `nanosec` failed later in rclpy's C conversion, in Python's internal words).
`construct_*` now refuses an integer outside its ROS type's range, or a value that is no integer, with a
ValueError/TypeError naming the field: a keyword argument, an array's item, a field of a message given as a
mapping. Bytes pass into a uint8 array as they are (an image is not copied item by item).

No mocks: rclpy's Jazzy message classes in this process, a real publish and subscription for the bytes.
"""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy

from tests.backends.values_td import values_td
from tests.ros2.common import build_rclpy

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

PACKAGE = "int_checks_bot_adaptor"


TD = values_td(
    "int-checks",
    {
        "small": "std_msgs/msg/UInt8",
        "big": "std_msgs/msg/Int64",
        "bytes": "std_msgs/msg/UInt8MultiArray",
        "wide": "std_msgs/msg/UInt64MultiArray",
        "stamped": "geometry_msgs/msg/PointStamped",
    },
)


def refused(call: Any, kind: type[Exception], *words: str) -> bool | str:
    try:
        call()
    except kind as exc:
        return all(word in str(exc) for word in words) or str(exc)
    except Exception as exc:  # noqa: BLE001 - the test reports which other error it was
        return f"{type(exc).__name__}: {exc}"
    return "built"


def test_rclpy_construct_refuses_integers_their_type_cannot_hold(ros2_domain: int, tmp_path: Path) -> None:
    import rclpy
    from rclpy.context import Context

    path = tmp_path / "td.json"
    path.write_text(json.dumps(TD), encoding="utf-8")
    _, package = build_rclpy(path, tmp_path / "src")
    sys.path.insert(0, str(package))
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("int_checks", context=context)
    try:
        module = importlib.import_module(PACKAGE)
        c = module.ValuesComponent(node, "checks")
        held = {
            "uint8 300": refused(lambda: c.construct_small_Msg(data=300), ValueError, "data", "0..255", "300"),
            "uint8 -1": refused(lambda: c.construct_small_Msg(data=-1), ValueError, "data", "uint8"),
            "int64 2**63": refused(lambda: c.construct_big_Msg(data=2**63), ValueError, "data", "int64"),
            "uint8[] item": refused(lambda: c.construct_bytes_Msg(data=[1, 256]), ValueError, "data[1]", "uint8"),
            "uint64[] item": refused(lambda: c.construct_wide_Msg(data=[0, -1]), ValueError, "data[1]", "uint64"),
            "nested mapping": refused(
                lambda: c.construct_stamped_Msg(header={"stamp": {"sec": 1, "nanosec": -1}}),
                ValueError,
                "Time.nanosec",
                "uint32",
            ),
            "nested layout": refused(
                lambda: c.construct_bytes_Msg(layout={"data_offset": 2**32}), ValueError, "data_offset", "uint32"
            ),
            "text": refused(lambda: c.construct_small_Msg(data="3"), TypeError, "data must be an integer, not str"),
            "float": refused(lambda: c.construct_big_Msg(data=2.5), TypeError, "data must be an integer, not float"),
        }
        assert held == dict.fromkeys(held, True), {k: v for k, v in held.items() if v is not True}
        # what the types hold is built, to their ends, numpy integers and bytes too
        assert c.construct_small_Msg(data=255).data == 255
        assert c.construct_big_Msg(data=-(2**63)).data == -(2**63)
        assert c.construct_big_Msg(data=numpy.int64(7)).data == 7
        assert list(c.construct_wide_Msg(data=[2**64 - 1]).data) == [2**64 - 1]
        image = bytes(range(256)) * 4
        assert bytes(c.construct_bytes_Msg(data=image).data) == image
        stamped = c.construct_stamped_Msg(header={"stamp": {"sec": -1, "nanosec": 2**32 - 1}})
        assert (stamped.header.stamp.sec, stamped.header.stamp.nanosec) == (-1, 2**32 - 1)
    finally:
        sys.path.remove(str(package))
        node.destroy_node()
        rclpy.shutdown(context=context)
