"""`--merge` and hand-written constraints: what the ROS type's own schema contradicts (scaffold/constraints)."""

from __future__ import annotations

from typing import Any

import pytest

from td2adaptor.scaffold.constraints import contradiction

UINT8 = {"type": "integer", "minimum": 0, "maximum": 255}
FIXED3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
BOUNDED5 = {"type": "array", "items": {"type": "number"}, "maxItems": 5}
STRING10 = {"type": "string", "maxLength": 10}


@pytest.mark.parametrize(
    ("key", "value", "ros", "reason"),
    [
        ("minimum", -1, UINT8, "below the minimum of uint8 (0..255)"),
        ("minimum", 10, UINT8, None),
        ("exclusiveMinimum", 255, UINT8, "leaves no value of uint8 (0..255)"),
        ("maximum", 300, UINT8, "above the maximum of uint8 (0..255)"),
        ("maximum", 100, UINT8, None),
        ("multipleOf", 0, UINT8, "not above 0"),
        ("minimum", 0.5, {"type": "number"}, None),
        ("maxItems", 2, FIXED3, "fewer than an array of exactly 3 items holds"),
        ("maxItems", 4, FIXED3, "more than an array of exactly 3 items holds"),
        ("maxItems", 6, BOUNDED5, "more than an array of at most 5 items holds"),
        ("maxItems", 4, BOUNDED5, None),
        ("maxItems", 100, {"type": "array", "items": {}}, None),
        ("minItems", 6, BOUNDED5, "more than an array of at most 5 items holds"),
        ("maxLength", 11, STRING10, "more than a string of at most 10 characters holds"),
        ("pattern", "^a", STRING10, None),
        ("maxLength", 3, UINT8, "the field is uint8 (0..255)"),
        ("const", 256, UINT8, "not a value of uint8 (0..255)"),
        ("const", 7, UINT8, None),
        ("minimum", "low", UINT8, "not a number"),
    ],
)
def test_the_ros_type_contradicts_only_what_it_cannot_hold(
    key: str, value: Any, ros: dict[str, Any], reason: str | None
) -> None:
    assert contradiction(key, value, ros) == reason
