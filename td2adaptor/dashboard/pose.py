"""Where a robot is, when its TD has a pose-like property: an object of numbers `x` and `y` (and `theta`, or
a quaternion `orientation` beside a `position`), found in the property's data schema, so that the map needs
no configuration (the RB-1's availability.localization_status.pose.pose, a nav_base's odometry
pose.pose.position)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

Pose = tuple[float, float, float | None]


@dataclass(frozen=True)
class PosePath:
    """Which property holds the pose, and where inside its value."""

    prop: str
    path: tuple[str, ...]  # to the object with x and y
    heading: str | None  # "theta" (a number beside x, y) or "quaternion" (a sibling `orientation`)


def _numbers(schema: Mapping[str, Any]) -> set[str]:
    props = schema.get("properties")
    if not isinstance(props, Mapping):
        return set()
    return {k for k, v in props.items() if isinstance(v, Mapping) and v.get("type") in ("number", "integer")}


def _candidates(schema: Any, path: tuple[str, ...]) -> list[tuple[int, tuple[str, ...], str | None]]:
    """(score, path, heading) of every object with numbers x and y, not inside an array (one pose per robot)."""
    if not isinstance(schema, Mapping) or schema.get("type") not in (None, "object"):
        return []
    found = []
    numbers = _numbers(schema)
    if {"x", "y"} <= numbers and "w" not in numbers:  # a quaternion also has x and y
        heading = "theta" if "theta" in numbers else None
        score = 3 if heading else 1
        if path and path[-1] == "position":
            score = 2
            heading = "quaternion"
        found.append((score + ("pose" in "/".join(path).lower()), path, heading))
    props = schema.get("properties")
    if isinstance(props, Mapping):
        for key, sub in props.items():
            found += _candidates(sub, (*path, str(key)))
    return found


def find_pose(td: Mapping[str, Any]) -> tuple[PosePath, ...]:
    """The best pose-like places among the TD's readable properties, all of one property (the first with the
    best score): a status message may hold more than one pose (the RB-1's localization and robot status), and
    `read_pose` takes the first that is set."""
    found: list[tuple[int, PosePath]] = []
    props = td.get("properties")
    if not isinstance(props, Mapping):
        return ()
    for name, prop in props.items():
        if not isinstance(prop, Mapping) or prop.get("writeOnly") is True:
            continue
        found += [(score, PosePath(str(name), path, heading)) for score, path, heading in _candidates(prop, ())]
    if not found:
        return ()
    best = max(score for score, _ in found)
    prop = next(where.prop for score, where in found if score == best)
    return tuple(where for score, where in found if score == best and where.prop == prop)


def _get(value: Any, path: tuple[str, ...]) -> Any:
    for key in path:
        if not isinstance(value, Mapping):
            return None
        value = value.get(key)
    return value


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def read_pose(places: tuple[PosePath, ...], value: Any) -> Pose | None:
    """The pose in a value of the property: the first of `places` that holds one other than all zeros (a field
    the robot leaves unset), else the first that holds one; None when none does."""
    poses = [pose for where in places if (pose := _read(where, value)) is not None]
    return next((p for p in poses if any(p)), poses[0] if poses else None)


def _read(where: PosePath, value: Any) -> Pose | None:
    node = _get(value, where.path)
    if not isinstance(node, Mapping):
        return None
    x, y = _number(node.get("x")), _number(node.get("y"))
    if x is None or y is None:
        return None
    heading: float | None = None
    if where.heading == "theta":
        heading = _number(node.get("theta"))
    elif where.heading == "quaternion":
        q = _get(value, (*where.path[:-1], "orientation"))
        if isinstance(q, Mapping):
            qx, qy, qz, qw = (_number(q.get(k)) for k in ("x", "y", "z", "w"))
            if None not in (qx, qy, qz, qw):
                assert qx is not None and qy is not None and qz is not None and qw is not None
                heading = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    return (x, y, heading)
