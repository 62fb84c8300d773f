"""What no event may carry to a robot (issue 30, items 1, 2 and 5): numbers that are not finite or do not fit
their ROS type, strings that are not Unicode text, nesting without end. Each is refused with `invalid-event`
naming where it is, on the envelope topics and the WoT topics alike, before anything runs; and every event
that reaches the node is answered, whatever it holds.

The rules (runtime/events.py `value_problem`, the float32 range in model/msgschema.py), the WoT adapter
(runtime/bus/thingbus.py), then the engine with the simulated RB-1 on the in-process bus.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from functools import cache
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import td2adaptor
from td2adaptor.model import Model
from td2adaptor.model.events import EventCatalog, Kind, build_catalog
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.bus.localbus import LocalBus
from td2adaptor.runtime.bus.thingbus import ThingBus
from td2adaptor.runtime.events import MAX_DEPTH, EventValidator, encode, references, salvage, value_problem
from td2adaptor.runtime.ros.simport import SimPort
from tests.conftest import REPO
from tests.runtime.edge import Recorder
from tests.runtime.rb1 import GOAL, check_outbound, rb1_catalog, rb1_model, rb1_validator, sim, terminal

ROBOT = "rb1_values"
T = f"td2adaptor/{ROBOT}"
W = f"{T}/{WOT_LEVEL}"
FLT_MAX = 3.4028234663852886e38
NAV_BASE = REPO / "examples" / "nav_base"


@cache
def nav_base() -> tuple[Model, EventCatalog, EventValidator]:
    result = td2adaptor.compile(NAV_BASE / "td.json", interfaces=[NAV_BASE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    catalog = build_catalog(result.model)
    return result.model, catalog, EventValidator(catalog)


def nested(depth: int) -> Any:
    """`depth` arrays inside one another."""
    value: Any = []
    for _ in range(depth - 1):
        value = [value]
    return value


def goal_at(x: str, **extra: Any) -> bytes:
    """The RB-1 goal with `x` written as the number literal `x` (which no JSON library writes)."""
    goal = {"procedure": {"goals": [{"pose": {"x": "@", "y": 3.0, "theta": 0.0}}]}, **extra}
    return json.dumps(goal).replace('"@"', x).encode()


# -- the rules -----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "pointer", "words"),
    [
        ({"a": [1, {"b": float("inf")}]}, "/a/1/b", "out of range"),
        ({"a": -float("inf")}, "/a", "must be finite"),
        ({"a": float("nan")}, "/a", "NaN"),
        ({"a": 10**400}, "/a", "out of range"),  # an integer no double holds
        ({"a": ["ok", "x\ud800y"]}, "/a/1", "lone surrogate (\\ud800)"),
        ({"a": {"k\udfff": 1}}, "/a/k\\udfff", "member name is not Unicode text"),  # the name shown escaped
        ({"a/b~c": float("inf")}, "/a~1b~0c", "out of range"),
        ({"p": nested(MAX_DEPTH)}, "/p" + "/0" * (MAX_DEPTH - 1), f"more than {MAX_DEPTH} levels"),
    ],
)
def test_value_problem_names_the_first_bad_place(data: Any, pointer: str, words: str) -> None:
    found = value_problem(data)
    assert found is not None and found[0] == pointer and words in found[1], found
    encode({"path": found[0], "message": found[1]})  # the refusal itself can be sent


@pytest.mark.parametrize(
    "data",
    [
        {"x": 1.7976931348623157e308, "y": -5e-324, "n": 2**64, "s": "héllo \U0001f916", "b": True, "z": None},
        {"p": nested(MAX_DEPTH - 1)},  # the event object and 63 levels below it
        [],
    ],
)
def test_value_problem_leaves_what_an_event_may_hold(data: Any) -> None:
    assert value_problem(data) is None


@pytest.mark.parametrize(
    ("raw", "pointer", "words"),
    [
        (b'{"payload":{"data":1e400}}', "/payload/data", "out of range"),
        (b'{"payload":{"data":-1e999}}', "/payload/data", "out of range"),
        (b'{"payload":{"data":Infinity}}', "/payload/data", "out of range"),
        (b'{"payload":{"data":NaN}}', "/payload/data", "NaN"),
        (b'{"payload":{"data":1' + b"0" * 400 + b"}}", "/payload/data", "out of range"),
        (b'{"correlation":"\\ud800","payload":{"data":1}}', "/correlation", "lone surrogate"),
        (b'{"id":"a\\udc00","payload":{"data":1}}', "/id", "lone surrogate"),
    ],
)
def test_a_write_holding_what_no_ros_number_or_text_is_an_invalid_event_naming_the_path(
    raw: bytes, pointer: str, words: str
) -> None:
    spec = rb1_catalog().find(Kind.WRITE, "door")
    event, problem = rb1_validator().parse(spec, ROBOT, raw)
    assert event is None and problem is not None
    assert problem.code == "invalid-event", problem
    assert problem.errors[0][0] == pointer and words in problem.errors[0][1], problem
    assert pointer in problem.message and "Infinity is not JSON" not in problem.message
    encode({"message": problem.message, "errors": problem.errors})


def test_an_integer_of_thousands_of_digits_is_out_of_range_not_python_words() -> None:
    spec = rb1_catalog().find(Kind.WRITE, "door")
    _, problem = rb1_validator().parse(spec, ROBOT, b'{"payload":{"data":' + b"9" * 5000 + b"}}")
    assert problem is not None and problem.code == "invalid-event", problem
    assert "out of range" in problem.message and "sys." not in problem.message and "4300" not in problem.message


def test_deep_nesting_is_an_invalid_event_at_any_depth() -> None:
    spec = rb1_catalog().find(Kind.QUERY, "gotoQuery")
    for depth in (MAX_DEPTH + 1, 500, 990, 5000):  # 5000: deeper than the JSON parser follows
        raw = json.dumps({"payload": nested(depth)}).encode() if depth < 990 else b"[" * depth + b"]" * depth
        _, problem = rb1_validator().parse(spec, ROBOT, raw)
        assert problem is not None and problem.code == "invalid-event", (depth, problem)
        assert f"nested more than {MAX_DEPTH} levels deep" in problem.message


def test_float32_fields_take_their_range_and_float64_fields_every_finite_number() -> None:
    _, catalog, validator = nav_base()
    dock = catalog.find(Kind.INVOKE, "dockRobot")  # max_staging_time: float32
    for value, ok in ((FLT_MAX, True), (-FLT_MAX, True), (3.5e38, False), (-3.5e38, False), (1e39, False)):
        raw = json.dumps({"payload": {"max_staging_time": value}}).encode()
        event, problem = validator.parse(dock, "nav", raw)
        assert (problem is None) is ok, (value, problem)
        if not ok:
            assert problem is not None and problem.code == "invalid-event"
            path, message = problem.errors[0]
            assert path == "/payload/max_staging_time" and ("maximum" in message or "minimum" in message), message
    # the documents say so too: the exposed TD's and the event schema's float32 member carries the range
    goal = dock.schema["properties"]["payload"]["properties"]["max_staging_time"]
    assert (goal["minimum"], goal["maximum"]) == (-FLT_MAX, FLT_MAX)
    nav = catalog.find(Kind.INVOKE, "navigateToPose")  # pose.pose.position.x: float64
    x = nav.schema["properties"]["payload"]["properties"]["pose"]["properties"]["pose"]["properties"]["position"]
    assert "maximum" not in x["properties"]["x"]
    raw = b'{"payload":{"pose":{"pose":{"position":{"x":1e300}}}}}'
    assert validator.parse(nav, "nav", raw)[1] is None


def test_a_correlation_that_is_no_text_is_never_echoed() -> None:
    assert references({"correlation": "ok", "mission": 3}) == ("ok", 3)
    assert references({"correlation": "no\ud800", "mission": 3}) == (None, 3)
    assert salvage(b'{"correlation":"no\\ud800","payload":5}') == (None, None)
    assert salvage(b'{"correlation":"yes","payload":5}') == ("yes", None)


@settings(max_examples=300, deadline=None)
@given(
    st.recursive(
        st.none() | st.booleans() | st.integers() | st.floats() | st.text(),
        lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner, max_size=4),
        max_leaves=20,
    ),
    st.sampled_from([float("inf"), float("-inf"), float("nan"), "\ud800", "a\udfffb", 10**309]),
)
def test_parse_refuses_any_event_with_a_poison_anywhere_and_the_refusal_can_be_sent(data: Any, poison: Any) -> None:
    """Whatever the event holds besides, a poison put in it is found, where it is, and the answer encodes."""
    spec = rb1_catalog().find(Kind.WRITE, "door")
    event = {"payload": {"data": data, "extra": [data, {"bad": poison}]}}
    raw = json.dumps(event, ensure_ascii=True).encode()  # `\ud800` as its escape, inf as Infinity, as senders do
    got, problem = rb1_validator().parse(spec, ROBOT, raw)
    assert got is None and problem is not None and problem.code == "invalid-event"
    found = value_problem(json.loads(raw))
    assert found is not None and problem.errors == (found,)
    assert (
        found[0].startswith("/payload/data")
        or found[0] == "/payload/extra/1/bad"
        or found[0].startswith("/payload/extra/0")
    )
    encode({"message": problem.message, "errors": problem.errors})


# -- the WoT adapter -----------------------------------------------------------------------------------------


def wot_bus(correlation_ids: bool = False) -> ThingBus:
    return ThingBus(LocalBus(LocalBroker(), "t"), rb1_catalog(), ROBOT, correlation_ids=correlation_ids)


@pytest.mark.parametrize("correlation_ids", [False, True])
def test_wrap_hands_every_message_on_whatever_it_holds(correlation_ids: bool) -> None:
    bus = wot_bus(correlation_ids)
    run = rb1_catalog().find(Kind.INVOKE, "gotoRun")
    door = rb1_catalog().find(Kind.WRITE, "door")
    for spec, raw in [
        (door, b'{"data":1e400}'),
        (run, b'{"correlationId":"\\ud800","procedure":{}}'),
        (run, b'{"correlationId":"' + b"\\ud800" * 200 + b'","procedure":{}}'),  # hashed into an id
        (run, b'{"procedure":{"k\\udfff":1}}'),
        (run, b"[" * 995 + b"]" * 995),  # deeper than the parser follows (or the writer, one level deeper)
        (run, b"[" * 900 + b"]" * 900),
        (run, b"\xff\xfe not utf-8"),
    ]:
        wrapped = bus.wrap(spec, raw)  # never raises
        _, problem = rb1_validator().parse(spec, ROBOT, wrapped)
        assert problem is not None, raw[:40]
        assert problem.code in ("invalid-event", "invalid-json"), (raw[:40], problem)
        assert "Infinity is not JSON" not in problem.message
    # 1e400 is refused as the envelope's would be: where it is, not as JSON the consumer never wrote
    _, problem = rb1_validator().parse(door, ROBOT, bus.wrap(door, b'{"data":1e400}'))
    assert problem is not None and problem.code == "invalid-event" and problem.errors[0][0] == "/payload/data"


# -- the engine ----------------------------------------------------------------------------------------------


class Rig:
    def __init__(self) -> None:
        self.broker = LocalBroker()
        self.model = rb1_model()
        self.sim = sim(0.2)
        # what the node sends (a recorder of everything would choke on the test's own deep messages)
        self.app = Recorder(self.broker, [f"{T}/error", f"{W}/error", f"{T}/+/+/feedback"])
        config = RuntimeConfig(robot=ROBOT, poll_period=0.02, property_period=0, state_dir="")
        self.engine = serve(self.model, SimPort(self.model, self.sim), config, broker=self.broker)

    def errors(self, topic: str = f"{T}/error") -> list[dict[str, Any]]:
        with self.app.cond:
            return [e for t, e in self.app.events if t == topic]

    def answered(self, count: int, topic: str = f"{T}/error") -> list[dict[str, Any]]:
        self.app.wait(lambda ev: sum(1 for t, _ in ev if t == topic) >= count)
        return self.errors(topic)

    def untouched(self) -> bool:
        return self.sim.next_id == 0 and self.sim.door_command is None and (self.sim.x, self.sim.y) == (0.0, 0.0)


@pytest.fixture
def rig() -> Iterator[Rig]:
    r = Rig()
    yield r
    r.engine.stop()
    check_outbound(r.app.events)


@pytest.mark.parametrize(
    ("topic", "raw", "pointer"),
    [
        (f"{T}/DoorComponent/door/write", b'{"correlation":"w1","payload":{"data":1e400}}', "/payload/data"),
        (f"{T}/GoToComponent/gotoRun", b'{"payload":' + goal_at("-1e400") + b"}", "/payload/procedure/goals/0/pose/x"),
        # a WoT message: the path in the message its consumer sent (it has no payload member)
        (f"{W}/DoorComponent/door", b'{"data":1e400}', "/data"),
        (f"{W}/GoToComponent/gotoRun", goal_at("1e999", correlationId="g2"), "/procedure/goals/0/pose/x"),
    ],
)
def test_a_number_no_double_holds_is_refused_naming_the_path_and_never_reaches_the_robot(
    rig: Rig, topic: str, raw: bytes, pointer: str
) -> None:
    rig.app.send(topic, raw)
    (error,) = rig.answered(1)
    assert error["payload"]["code"] == "invalid-event", error
    assert error["payload"]["errors"][0]["path"] == pointer and pointer in error["payload"]["message"]
    assert "Infinity" not in error["payload"]["message"] and error["payload"]["topic"] == topic
    if topic.startswith(W):
        (wot,) = rig.answered(1, f"{W}/error")  # the WoT consumers' form of the same answer
        assert wot["code"] == "invalid-event" and wot["errors"][0]["path"] == pointer and wot["topic"] == topic
    # the robot was never called: a valid event afterwards is the first it sees
    rig.app.send(f"{T}/GoToComponent/gotoRun", json.dumps({"correlation": "fine", "payload": GOAL}).encode())
    rig.app.wait(terminal("feedback", "fine"))
    assert rig.sim.next_id == 1 and rig.sim.door_command is None
    if not topic.startswith(W):  # an envelope event's refusal: no WoT consumer sent it, none is told
        assert rig.errors(f"{W}/error") == []


def test_a_lone_surrogate_anywhere_is_refused_before_anything_runs_and_answered(rig: Rig) -> None:
    invoke = f"{T}/GoToComponent/gotoRun"
    sent = [
        (invoke, b'{"correlation":"\\ud800","payload":' + json.dumps(GOAL).encode() + b"}"),  # valid but for it
        (f"{T}/GoToComponent/gotoQuery", b'{"id":"\\ud800"}'),  # was `internal` (the id store's traceback)
        (invoke, b'{"correlation":"\\ud800","payload":5}'),  # invalid twice over: was never answered
        (invoke, b'{"correlation":"c4","payload":{"procedure":{"goals\\udbff":[]}}}'),  # a member name
        (f"{W}/GoToComponent/gotoRun", b'{"correlationId":"\\udc00","procedure":{}}'),
        (f"{W}/DoorComponent/door", b'{"data":"\\ud83d"}'),
    ]
    for topic, raw in sent:
        rig.app.send(topic, raw)
    errors = rig.answered(len(sent))
    assert len(errors) == len(sent)
    assert [e["payload"]["code"] for e in errors] == ["invalid-event"] * len(sent), errors
    paths = sorted(e["payload"]["errors"][0]["path"] for e in errors)
    assert paths == sorted(
        ["/correlation", "/id", "/correlation", "/payload/procedure/goals\\udbff", "/correlationId", "/data"]
    )
    # nothing that cannot be encoded is echoed; what can be is
    assert [e.get("correlation") for e in errors if "correlation" in e] == ["c4"]
    assert rig.untouched()
    # the WoT consumers are told about the two WoT messages, in their own terms; not about the envelope events
    wot = rig.answered(2, f"{W}/error")
    assert sorted(e["errors"][0]["path"] for e in wot) == ["/correlationId", "/data"]
    assert {e["topic"] for e in wot} == {topic for topic, _ in sent if topic.startswith(W)}


def test_nesting_deeper_than_the_parser_follows_is_answered_on_both_topics(rig: Rig) -> None:
    deep = b"[" * 1200 + b"]" * 1200
    rig.app.send(f"{W}/GoToComponent/gotoQuery", deep)  # was a RecursionError in the adapter: no answer
    rig.app.send(f"{T}/GoToComponent/gotoQuery", deep)
    rig.app.send(f"{W}/GoToComponent/gotoRun", json.dumps({"procedure": nested(200)}).encode())
    errors = rig.answered(3)
    assert [e["payload"]["code"] for e in errors] == ["invalid-event"] * 3
    assert all("levels deep" in e["payload"]["message"] for e in errors)
    assert rig.untouched()
