"""Generated mROS message classes speak exactly rosbags' ROS 1 wire format (host harness, tests/backends/mros/wire.py).

Every message type of the feature application (all primitives, time/duration, fixed and variable arrays of
primitives, strings, messages and empty messages, nesting, the RB-1 types) is checked with
hypothesis-generated values: memCopy gives the bytes of `serialize_ros1`, dataSize() their length, the
bounded decoder and mROS's callback path give back the values, the contract's deserialize consumes exactly
the message; empty and maximal messages; truncated and random input never crashes and is refused when
truncated; the traits carry the ROS 1 md5, datatype and full definition.
"""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from td2adaptor.backends.mros.types import TypeViews
from tests.backends.mros import fixtures, wire

# the session fixtures this module uses
shared_root = fixtures.shared_root
generated = fixtures.generated
feature_views = fixtures.feature_views
typestore = fixtures.typestore
wire_harness = fixtures.wire_harness

SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
CAPS = (64, 8)


def _names(views: TypeViews) -> list[str]:
    return list(views.order)


def _serialize(ts: Any, views: TypeViews, name: str, value: list[Any]) -> str:
    return bytes(ts.serialize_ros1(wire.to_rosbags(ts, views.table, name, value), name)).hex()


def _join(tokens: list[str]) -> str:
    return "".join(" " + t for t in tokens)


def test_traits_are_the_ros1_digests(wire_harness: wire.Harness, feature_views: TypeViews, typestore: Any) -> None:
    table = feature_views.table
    ids = set()
    for name in feature_views.order:
        view = feature_views.views[name]
        md5, datatype, definition, type_id = wire_harness.ask(f"T {view.msg_id}").split(" ")
        digest = table.ros1_digest(name)
        assert md5 == digest.md5, name
        assert bytes.fromhex(definition).decode("utf-8") == digest.definition, name
        assert datatype == name.replace("/msg/", "/")
        assert int(type_id) == view.msg_id
        ids.add(view.msg_id)
        text, rosbags_md5 = typestore.generate_msgdef(name)
        if not any(c.type == "bool" for n in _closure(feature_views, name) for c in table.message(n).constants):
            # rosbags writes bool constants as True/False before hashing; genmsg (and the model) hash the
            # text as written ("bool B_TRUE=1"), so only types without bool constants can agree
            assert (text, rosbags_md5) == (digest.definition, digest.md5), name
    assert len(ids) == len(feature_views.order)


def _closure(views: TypeViews, name: str) -> set[str]:
    out = {name}
    for f in views.table.message(name).fields:
        if f.type.is_message:
            out |= _closure(views, f.type.base)
    return out


@SETTINGS
@given(data=st.data())
def test_encode_and_decode_match_rosbags(
    data: st.DataObject, wire_harness: wire.Harness, feature_views: TypeViews, typestore: Any
) -> None:
    name = data.draw(st.sampled_from(_names(feature_views)))
    view = feature_views.views[name]
    value = data.draw(wire.message_values(feature_views.table, name, CAPS))
    tokens = wire.tokens(feature_views.table, name, value)
    expected = _serialize(typestore, feature_views, name, value)
    encoded, size = wire_harness.ask(f"E {view.msg_id}{_join(tokens)}").split(" ")
    assert encoded == expected
    assert int(size) == len(expected) // 2
    assert wire_harness.ask(f"D {view.msg_id} {expected}") == "ok 0" + _join(tokens)
    assert wire_harness.ask(f"C {view.msg_id} {expected}") == "cb" + _join(tokens)
    assert wire_harness.ask(f"U {view.msg_id} {expected}") == f"{len(expected) // 2}" + _join(tokens)
    # and rosbags reads our bytes back to the same message
    again = typestore.deserialize_ros1(bytes.fromhex(encoded), name)
    assert bytes(typestore.serialize_ros1(again, name)).hex() == expected


@pytest.mark.parametrize("size", ["empty", "max"])
def test_empty_and_maximal_messages(
    size: str, wire_harness: wire.Harness, feature_views: TypeViews, typestore: Any
) -> None:
    for name in feature_views.order:
        view = feature_views.views[name]
        value = wire.fixed_value(feature_views.table, name, CAPS, size)
        tokens = wire.tokens(feature_views.table, name, value)
        expected = _serialize(typestore, feature_views, name, value)
        encoded, length = wire_harness.ask(f"E {view.msg_id}{_join(tokens)}").split(" ")
        assert encoded == expected, name
        assert wire_harness.ask(f"D {view.msg_id} {expected}") == "ok 0" + _join(tokens), name
        bound = feature_views.size(name)
        if size == "empty":
            assert wire_harness.ask(f"Z {view.msg_id}") == expected, name  # defaults are zeros and empties
            assert int(length) == bound.min, name
        else:
            assert int(length) == bound.max, name  # the pool sizing bound is exact for maximal messages


@SETTINGS
@given(data=st.data())
def test_truncated_and_random_input_is_refused_safely(
    data: st.DataObject, wire_harness: wire.Harness, feature_views: TypeViews, typestore: Any
) -> None:
    name = data.draw(st.sampled_from(_names(feature_views)))
    view = feature_views.views[name]
    value = data.draw(wire.message_values(feature_views.table, name, CAPS))
    full = bytes.fromhex(_serialize(typestore, feature_views, name, value))
    if full:
        cut = data.draw(st.integers(0, len(full) - 1))
        assert wire_harness.ask(f"D {view.msg_id} {full[:cut].hex()}") == "fail"
        assert wire_harness.ask(f"C {view.msg_id} {full[:cut].hex()}") == "dropped"
    noise = data.draw(st.binary(max_size=256) | st.just(b"\xff\xff\xff\x7f" * 4))
    reply = wire_harness.ask(f"D {view.msg_id} {noise.hex()}")
    assert reply == "fail" or reply.startswith("ok ")
    assert wire_harness.ask(f"C {view.msg_id} {noise.hex()}").split(" ")[0] in ("cb", "dropped")


@settings(max_examples=50, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_swap_exchanges_whole_messages(
    data: st.DataObject, wire_harness: wire.Harness, feature_views: TypeViews, typestore: Any
) -> None:
    name = data.draw(st.sampled_from(_names(feature_views)))
    view = feature_views.views[name]
    value = data.draw(wire.message_values(feature_views.table, name, CAPS))
    tokens = wire.tokens(feature_views.table, name, value)
    swapped_first, swapped_second = wire_harness.ask(f"S {view.msg_id}{_join(tokens)}").split(" ")
    assert swapped_second == _serialize(typestore, feature_views, name, value)
    assert swapped_first == wire_harness.ask(f"Z {view.msg_id}")
