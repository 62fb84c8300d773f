"""The engine's fast first check of inbound events (runtime/engine/precheck.py) decides exactly as the Python
validator does: what it lets through is valid, and everything else is the Python validator's verdict, words
and all. Checked on the examples' catalogs with events written to sit on the edges where the Rust and the
Python validators could differ (integers at 64-bit bounds, regular-expression dialects, types), and with
random events (hypothesis)."""

from __future__ import annotations

import json
from functools import cache
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import td2adaptor
from td2adaptor.model.events import EventCatalog, EventSpec, Kind, build_catalog
from td2adaptor.runtime.engine.precheck import FastCheck, comparable
from td2adaptor.runtime.events import EventValidator
from tests.conftest import REPO
from tests.runtime.rb1 import GOAL, rb1_catalog, rb1_model

ROBOT = "rb1_precheck"
NAV_BASE = REPO / "examples" / "nav_base"


@cache
def nav_catalog() -> EventCatalog:
    result = td2adaptor.compile(NAV_BASE / "td.json", interfaces=[NAV_BASE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return build_catalog(result.model)


@cache
def checks(which: str) -> tuple[EventCatalog, EventValidator, FastCheck]:
    catalog = rb1_catalog() if which == "rb1" else nav_catalog()
    validator = EventValidator(catalog)
    return catalog, validator, FastCheck(catalog, validator)


def same(which: str, spec: EventSpec, raw: bytes, robot: str = ROBOT) -> tuple[Any, Any]:
    """Both verdicts on `raw`, asserted equal; the fast one."""
    _, validator, fast = checks(which)
    expected = validator.parse(spec, robot, raw)
    got = fast.parse(spec, robot, raw)
    assert got == expected, (spec.key, raw[:300])
    return got


def inbound(which: str) -> list[EventSpec]:
    return [s for s in checks(which)[0].specs if s.kind.inbound]


EDGES: list[Any] = [
    {},
    {"correlation": "c1"},
    {"correlation": "c1", "mission": 3},
    {"correlation": "c1", "mission": 2**64 - 1},
    {"correlation": "c1", "mission": 2**64},
    {"correlation": "c1", "mission": -(2**63)},
    {"correlation": "c1", "mission": -(2**63) - 1},
    {"correlation": "c1", "mission": 1.0},
    {"correlation": "c1", "mission": True},
    {"correlation": "c1", "mission": "3"},
    {"correlation": ""},
    {"correlation": "x" * 300},
    {"correlation": 5},
    {"robot": ROBOT},
    {"robot": "other"},
    {"robot": ROBOT + "\n"},
    {"robot": "all"},
    {"time": "2026-05-01T12:00:00Z"},
    {"time": "2026-05-01T12:00:00Z\n"},
    {"time": "٢٠٢٦-05-01T12:00:00Z"},
    {"time": "2026-05-01T12:00:00.123456789+02:00"},
    {"time": "yesterday"},
    {"id": "e1", "type": "invoke"},
    {"id": 7},
    {"source": "app"},
    {"unknown": 1},
    {"payload": GOAL},
    {"payload": {"procedure": {"goals": [{"pose": {"x": "1", "y": 0.0, "theta": 0.0}}]}}},
    {"payload": {"procedure": {"goals": [{"pose": {"x": 1, "y": 0, "theta": 0}}]}}},
    {"payload": {"procedure": {"goals": []}}},
    {"payload": {"procedure": {"goals": [{"pose": {"x": 1.0}, "extra": 1}]}}},
    {"payload": {"goal": "g"}},
    {"payload": {"data": True}},
    {"payload": {"data": 1}},
    {"payload": {"data": 2**64}},
    {"payload": {"data": -1}},
    {"payload": {"data": "\ufeff"}},
    {"payload": None},
    {"payload": []},
    {"payload": {"max_staging_time": 3.5e38}},
    {"payload": {"max_staging_time": 3.4e38}},
    {"payload": {"pose": {"header": {"frame_id": "map\n"}, "pose": {"position": {"x": 1e300}}}}},
    {"payload": {"pose": {"header": {"stamp": {"sec": 2**31, "nanosec": 2**32}}}}},
    {"payload": {"pose": {"header": {"stamp": {"sec": 2**31 - 1, "nanosec": 2**32 - 1}}}}},
]
RAWS = [b"", b"[]", b"null", b"3", b'"x"', b"{", b"\xff\xfe", b'{"payload": NaN}', b'{"payload": 1e400}']


@pytest.mark.parametrize("which", ["rb1", "nav"])
def test_the_fast_check_gives_the_python_validators_verdict_on_the_edges(which: str) -> None:
    fast_ones = 0
    for spec in inbound(which):
        for event in EDGES:
            event_, problem = same(which, spec, json.dumps(event).encode())
            fast_ones += problem is None
        for raw in RAWS:
            same(which, spec, raw)
        same(which, spec, b'{"robot": "%s"}' % ROBOT.encode(), robot="someone")
    assert fast_ones > 0  # some of them were valid: the Rust path was taken


def test_every_example_event_kind_is_checked_in_rust() -> None:
    """The examples' schemas hold nothing left to Python: their events take the fast path."""
    for which in ("rb1", "nav"):
        _, _, fast = checks(which)
        for spec in inbound(which):
            assert fast.compiled(spec), spec.key


def test_schemas_the_two_validators_may_judge_differently_are_left_to_python() -> None:
    envelope = frozenset({"^[a-z]+$"})
    assert comparable({"type": "object", "properties": {"a": {"pattern": "^[a-z]+$"}}}, envelope)
    assert not comparable({"properties": {"a": {"type": "string", "pattern": "^\\s*$"}}}, envelope)
    for keyword in ("patternProperties", "multipleOf", "uniqueItems", "format"):
        assert not comparable({"properties": {"a": {keyword: 1}}}, envelope), keyword
    assert not comparable({"properties": {"pattern": {"type": "string"}}}, envelope)  # a member named so: safe side


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=False)
    | st.text(max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=6), children, max_size=3),
    max_leaves=12,
)
members = st.sampled_from(["correlation", "mission", "payload", "robot", "time", "id", "type", "source", "x"])


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(["rb1", "nav"]), st.data(), st.dictionaries(members, json_values, max_size=4))
def test_random_events_get_the_python_validators_verdict(which: str, data: st.DataObject, event: Any) -> None:
    spec = data.draw(st.sampled_from(inbound(which)))
    if data.draw(st.booleans()) and spec.kind is Kind.INVOKE:
        event["payload"] = GOAL
    same(which, spec, json.dumps(event).encode())


def test_the_engines_of_one_td_share_their_rust_validators() -> None:
    """A fleet of one TD compiles them once (each robot's own registry and validators cost 1.2 MiB: 118 MiB for
    100 RB-1s), another TD has its own."""
    first, second = (FastCheck(c, EventValidator(c)) for c in (build_catalog(rb1_model()), build_catalog(rb1_model())))
    assert first._compiled is second._compiled
    assert checks("nav")[2]._compiled is not first._compiled
