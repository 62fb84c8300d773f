"""runtime/ros/cdr.py against rclpy itself: random messages of every test_msgs type (and the sensor messages streamed
as properties) serialized by rclpy's own typesupport (real Fast DDS CDR) must decode to exactly what
`genport.to_plain` gives for the message rclpy deserializes from the same bytes (what a subscription hands the
edge node: float32 values already rounded), the same JSON text byte for byte. No mocks.
"""

from __future__ import annotations

import importlib
import json
import math
import random
from typing import Any

import pytest

from tests.tools import require_module

require_module("rclpy", "the ROS 2 wheels: bash .ci/setup-ros2.sh")

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from td2adaptor.model.primitives import INT_RANGES  # noqa: E402
from td2adaptor.runtime.engine.streams import plain  # noqa: E402
from td2adaptor.runtime.ros.cdr import CdrError, decoder  # noqa: E402
from td2adaptor.runtime.ros.genport import to_plain  # noqa: E402

_FLOATS = [0.0, -0.0, 0.1, -2.5e10, 1e-300, 3.4e38, math.nan, math.inf, -math.inf, 12345.678]
_TEXT = ["", "a", "odom", "grüße €", "😀 robot", "x" * 40]


def _class(named: Any) -> type:
    cls: type = getattr(importlib.import_module(".".join(named.namespaces)), named.name)
    return cls


def _basic(rng: random.Random, typename: str) -> Any:
    if typename == "boolean":
        return rng.random() < 0.5
    if typename == "octet":
        return bytes([rng.randrange(256)])
    if typename in ("float", "double"):
        return rng.choice(_FLOATS) if rng.random() < 0.5 else rng.uniform(-1e6, 1e6)
    low, high = INT_RANGES[typename]
    return rng.choice([low, high, 0, rng.randint(low, high)])


def _element(rng: random.Random, slot: Any) -> Any:
    kind = type(slot).__name__
    if kind == "BasicType":
        return _basic(rng, slot.typename)
    if kind in ("UnboundedString", "BoundedString"):
        text = rng.choice(_TEXT)
        return text[: slot.maximum_size] if kind == "BoundedString" else text
    if kind == "NamespacedType":
        return random_message(rng, _class(slot))
    raise AssertionError(f"no generator for {kind}")


def _value(rng: random.Random, slot: Any) -> Any:
    kind = type(slot).__name__
    if kind == "Array":
        return [_element(rng, slot.value_type) for _ in range(slot.size)]
    if kind in ("UnboundedSequence", "BoundedSequence"):
        most = slot.maximum_size if kind == "BoundedSequence" else 6
        return [_element(rng, slot.value_type) for _ in range(rng.randint(0, most))]
    return _element(rng, slot)


def random_message(rng: random.Random, cls: type) -> Any:
    msg = cls()
    names = list(cls.get_fields_and_field_types())  # type: ignore[attr-defined]
    for name, slot in zip(names, cls.SLOT_TYPES, strict=True):  # type: ignore[attr-defined]
        if rng.random() < 0.15:
            continue  # the field's default
        setattr(msg, name, _value(rng, slot))
    return msg


def _test_msgs() -> list[type]:
    module = importlib.import_module("test_msgs.msg")
    return [getattr(module, n) for n in sorted(dir(module)) if hasattr(getattr(module, n), "SLOT_TYPES")]


def _sensor_msgs() -> list[type]:
    names = [
        "nav_msgs.msg.Odometry",
        "sensor_msgs.msg.LaserScan",
        "sensor_msgs.msg.JointState",
        "sensor_msgs.msg.BatteryState",
        "sensor_msgs.msg.PointCloud2",
        "sensor_msgs.msg.Imu",
        "diagnostic_msgs.msg.DiagnosticArray",
        "geometry_msgs.msg.PoseArray",
        "std_msgs.msg.Empty",
        "action_msgs.msg.GoalStatusArray",
    ]
    out = []
    for dotted in names:
        module, _, name = dotted.rpartition(".")
        try:
            out.append(getattr(importlib.import_module(module), name))
        except ImportError:
            continue
    return out


TYPES = [t for t in _test_msgs() if t.__name__ != "WStrings"] + _sensor_msgs()


@pytest.mark.parametrize("cls", TYPES, ids=lambda c: f"{c.__module__.split('.')[0]}/{c.__name__}")
def test_random_messages_decode_as_to_plain_gives(cls: type) -> None:
    decode = decoder(cls)
    assert decode is not None, f"{cls.__name__} has no decoder"
    rng = random.Random(f"cdr-{cls.__module__}-{cls.__name__}")
    for _ in range(60):
        msg = random_message(rng, cls)
        data = serialize_message(msg)
        received = deserialize_message(data, cls)
        expected = to_plain(received)
        got = decode(data)
        assert got == expected
        assert json.dumps(got) == json.dumps(expected)  # the same event text (types, order, None for NaN)
        assert json.dumps(plain(received)) == json.dumps(got)


def test_defaults_of_every_type() -> None:
    for cls in TYPES:
        decode = decoder(cls)
        assert decode is not None
        data = serialize_message(cls())
        assert json.dumps(decode(data)) == json.dumps(to_plain(deserialize_message(data, cls)))


def test_wide_strings_are_left_to_rclpy() -> None:
    from test_msgs.msg import WStrings

    assert decoder(WStrings) is None


def test_bytes_that_are_not_the_message_are_refused() -> None:
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    scan = LaserScan(ranges=[1.0] * 720)
    for cls, msg in ((Odometry, Odometry()), (LaserScan, scan)):
        decode = decoder(cls)
        assert decode is not None
        data = serialize_message(msg)
        with pytest.raises(CdrError, match="missing|not a"):
            decode(data[: len(data) // 2])
        with pytest.raises(CdrError, match="little-endian"):
            decode(b"\x00\x00" + data[2:])  # big-endian CDR: rclpy reads it, this module does not
    with pytest.raises(CdrError):
        decoder(LaserScan)(b"\x00\x01\x00\x00" + b"\xff" * 40)  # type: ignore[misc]  # a huge count


def test_the_generated_source_names_only_fields() -> None:
    from nav_msgs.msg import Odometry

    decode = decoder(Odometry)
    source = decode.source  # type: ignore[union-attr]
    assert "'covariance': floats(" in source
    assert "import" not in source and "__" not in source
