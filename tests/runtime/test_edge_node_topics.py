"""Issue 35, items 11 and 12, on a real mosquitto: what the edge node subscribes and to whom it answers.

* A command on a topic of the robot where no event is defined (an affordance or component it does not have,
  in the envelope or the WoT tree) is answered `unknown-topic`, on the tree it came on; what the node publishes
  itself under its command filters (property values, the WoT error topic) is neither answered nor run, and a
  retained message on an unknown topic (someone's data, not a command) is not answered.
* A refusal of an envelope event (`expired`, `from-the-future`, `id-reused`, `invalid-event`) concerns a
  message no WoT consumer sent: it is not mirrored to `wot-thing/error`. A refused WoT message is answered in
  the terms of what its consumer sent: `/procedure/goals/0/pose/x` (no `/payload`), `/correlationId`, and an
  unexpected member of a query or cancel input by its own name.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from td2adaptor.model.events import Kind, command_filters
from td2adaptor.model.wot import CORRELATION, wot_command_filters, wot_topic
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.bus.bus import topic_matches
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient, Event
from tests.runtime.edge import bus_of
from tests.runtime.rb1 import GOAL, check_outbound, rb1_catalog, rb1_model, sim, terminal

ROBOT = "rb1_topics"
T = f"td2adaptor/{ROBOT}"
W = f"{T}/wot-thing"


@pytest.fixture
def node(broker: Mosquitto) -> Iterator[tuple[Engine, AppClient]]:
    """The RB-1 served over mosquitto with its property values flowing (the node's own traffic under its
    command filters), and an application that records everything under the robot's topics."""
    model = rb1_model()
    config = RuntimeConfig(
        robot=ROBOT, bus=broker.url, poll_period=0.05, property_period=0.05, call_timeout=2, state_dir=""
    )
    engine = serve(model, SimPort(model, sim(0.2)), config)
    app = AppClient(broker, [f"{T}/#"])
    try:
        yield engine, app
    finally:
        app.close()
        engine.stop()


def errors(events: list[Event], tree: str = "envelope") -> list[dict[str, Any]]:
    """The error events the node sent: the envelope's (`payload` inside), or their WoT form."""
    topic = f"{T}/error" if tree == "envelope" else f"{W}/error"
    return [e for t, e in events if t == topic]


def sent_by_node(events: list[Event], sent: set[str]) -> list[Event]:
    return [(t, e) for t, e in events if t not in sent]


def test_the_node_subscribes_filters_that_never_match_its_feedback_state_or_status_topics() -> None:
    catalog = rb1_catalog()
    filters = [*command_filters(catalog, ROBOT), *wot_command_filters(ROBOT)]
    assert filters[0] == f"{T}/+/+" and f"{T}/GoToComponent/+/query" in filters and f"{W}/+/+/cancel" in filters
    for spec in catalog.specs:
        for topic in (spec.topic(ROBOT), wot_topic(spec, ROBOT)):
            if topic is None:
                continue
            matched = [f for f in filters if topic_matches(f, topic)]
            if spec.kind.inbound:  # every command topic is matched, by one filter (a message is delivered once)
                assert len(matched) == 1, (topic, matched)
            elif spec.kind is Kind.PROPERTY or topic == f"{W}/error":  # on the level of commands: dropped
                assert len(matched) == 1, (topic, matched)
            else:  # feedback, state, the envelope error, the status: never sent to the node
                assert matched == [], (topic, matched)
    # unknown topics of every command shape, in both trees, each matched once too
    for topic in (f"{T}/NoSuch/x", f"{T}/DoorComponent/x/write", f"{W}/X/write", f"{W}/X/y/cancel", f"{W}/X/y"):
        assert sum(topic_matches(f, topic) for f in filters) == 1, topic


def test_a_command_on_an_unknown_topic_is_answered_on_the_tree_it_came_on(
    node: tuple[Engine, AppClient],
) -> None:
    engine, app = node
    app.wait(lambda ev: any(t == f"{W}/PoseMarkerComponent/poseMarker" for t, _ in ev))  # its own values flow
    unknown_envelope = [
        f"{T}/GoToComponent/noSuchAction",  # an affordance the component does not have
        f"{T}/NoSuchComponent/gotoRun",  # a component the robot does not have
        f"{T}/DoorComponent/window/write",  # a write of a property it does not have
        f"{T}/GoToComponent/gotoRun/cancel",  # gotoRun is no ROS action: its goal has no cancel topic
    ]
    unknown_wot = [f"{W}/GoToComponent/noSuchAction", f"{W}/GoToComponent/gotoRun/query"]
    for n, topic in enumerate(unknown_envelope):
        app.send(topic, {"correlation": f"e{n}", "payload": GOAL})
    for n, topic in enumerate(unknown_wot):
        app.send(topic, {**GOAL, CORRELATION: f"w{n}"})
    events = app.wait(lambda ev: len(errors(ev)) >= 6 and len(errors(ev, "wot")) >= 2)
    envelope = {e["payload"]["topic"]: e for e in errors(events)}
    assert set(envelope) == {*unknown_envelope, *unknown_wot}
    assert {e["payload"]["code"] for e in envelope.values()} == {"unknown-topic"}
    assert all("affordance" not in e for e in envelope.values())
    assert [envelope[t]["correlation"] for t in unknown_envelope] == ["e0", "e1", "e2", "e3"]  # its answer
    wot = errors(events, "wot")  # the WoT consumer is answered on its own error topic, the envelope's never
    assert sorted(e["topic"] for e in wot) == sorted(unknown_wot) and {e["code"] for e in wot} == {"unknown-topic"}
    assert sorted(e[CORRELATION] for e in wot) == ["w0", "w1"]
    assert "Thing Description" in wot[0]["message"]

    # known commands still run, and the node's own property values (envelope and WoT, under the command
    # filters) were neither answered nor taken as commands: the engine took exactly what the test sent
    app.send(f"{T}/GoToComponent/gotoRun", {"correlation": "fine", "payload": GOAL})
    app.wait(terminal("feedback", "fine"))
    app.send(f"{W}/GoToComponent/gotoRun", {**GOAL, CORRELATION: "fine-wot"})
    app.wait(lambda ev: any(e.get(CORRELATION) == "fine-wot" and e.get("terminal") for _, e in ev))
    assert len(errors(app.events)) == 6 and engine.stats.get("refused", 0) == 0
    assert engine.stats["in"] == len(unknown_envelope) + len(unknown_wot) + 2, engine.stats
    sent = {*unknown_envelope, *unknown_wot, f"{T}/GoToComponent/gotoRun", f"{W}/GoToComponent/gotoRun"}
    assert check_outbound(sent_by_node(app.events, sent)) > 0


def test_the_broker_does_not_send_the_node_its_own_property_values(node: tuple[Engine, AppClient]) -> None:
    """MQTT 5 no-local on the node's subscriptions: its command filters match its property values' topics, and
    without it every value (envelope and WoT) would come back to it, only to be dropped."""
    engine, app = node
    seen: list[str] = []
    bus_of(engine).subscribe(f"{T}/+/+", lambda m: seen.append(m.topic))  # what this connection receives there
    bus_of(engine).subscribe(f"{W}/+/+", lambda m: seen.append(m.topic), qos=0)  # as the node: no resubscribe
    values = f"{T}/AvailabilityComponent/availability"
    before = sum(t == values for t, _ in app.events)
    app.send(f"{T}/GoToComponent/gotoRun", {"correlation": "move", "payload": GOAL})  # what others send arrives
    app.wait(terminal("feedback", "move"))
    app.wait(lambda ev: sum(t == values for t, _ in ev) >= before + 2)  # it published values of the move
    app.send(f"{T}/GoToComponent/noSuchAction", {"correlation": "probe"})
    app.wait(lambda ev: any(e.get("correlation") == "probe" for e in errors(ev)))
    assert seen == [f"{T}/GoToComponent/gotoRun", f"{T}/GoToComponent/noSuchAction"], seen[:5]


def test_a_retained_message_on_an_unknown_topic_is_someones_data_not_a_command(
    node: tuple[Engine, AppClient],
) -> None:
    engine, app = node
    stale = f"{T}/OldComponent/oldValue"  # e.g. what an earlier version of this robot's node published
    app.client.publish(stale, json.dumps({"data": 1}).encode(), qos=1, retain=True).wait_for_publish(10)
    app.send(f"{T}/GoToComponent/noSuchAction", {"correlation": "after"})  # answered: the stale one was not
    events = app.wait(lambda ev: any(e.get("correlation") == "after" for e in errors(ev)))
    assert [e["payload"]["topic"] for e in errors(events)] == [f"{T}/GoToComponent/noSuchAction"]
    assert engine.stats.get("unknown-retained") == 1
    app.client.publish(stale, b"", qos=1, retain=True).wait_for_publish(10)


def test_envelope_refusals_are_not_mirrored_to_wot_consumers(node: tuple[Engine, AppClient]) -> None:
    _, app = node
    query = f"{T}/GoToComponent/gotoQuery"
    app.send(query, {"id": "old", "time": "2020-01-01T00:00:00Z", "correlation": "expired"})
    app.send(query, {"id": "late", "time": "2099-01-01T00:00:00Z", "correlation": "future"})
    app.send(f"{T}/DoorComponent/door/write", {"id": "twice", "payload": {"data": 0.5}})  # runs
    app.send(query, {"id": "twice", "correlation": "reused"})
    app.send(query, {"correlation": "invalid", "mission": "seven"})
    # then a WoT message refused: its answer is the one the WoT consumers see
    app.send(f"{W}/GoToComponent/gotoQuery", {"mission": "seven", CORRELATION: "wot-invalid"})
    events = app.wait(lambda ev: len(errors(ev, "wot")) >= 1 and len(errors(ev)) >= 5)
    codes = {e["correlation"]: e["payload"]["code"] for e in errors(events)}
    assert codes == {
        "expired": "expired",
        "future": "from-the-future",
        "reused": "id-reused",
        "invalid": "invalid-event",
        "wot-invalid": "invalid-event",
    }
    (wot,) = errors(app.events, "wot")
    assert (wot[CORRELATION], wot["topic"], wot["errors"][0]["path"]) == (
        "wot-invalid",
        f"{W}/GoToComponent/gotoQuery",
        "/mission",
    )


@pytest.mark.parametrize(
    ("affordance", "data", "path", "words"),
    [
        (
            "GoToComponent/gotoRun",
            {"procedure": {"goals": [{"pose": {"x": "far", "y": 3.0, "theta": 0.0}}]}, CORRELATION: "w"},
            "/procedure/goals/0/pose/x",
            "'far' is not of type 'number'",
        ),
        ("GoToComponent/gotoRun", {**GOAL, CORRELATION: 5}, "/correlationId", "5 is not of type 'string'"),
        ("DoorComponent/door", {"data": "fast"}, "/data", "'fast' is not of type 'number'"),
        ("GoToComponent/gotoQuery", {"which": 1, CORRELATION: "w"}, "/which", "'which' was unexpected"),
        ("GoToComponent/gotoCancel", [1], "", "gotoCancel takes only mission and correlationId"),
    ],
)
def test_a_refused_wot_message_is_answered_in_the_terms_of_what_its_consumer_sent(
    node: tuple[Engine, AppClient], affordance: str, data: Any, path: str, words: str
) -> None:
    _, app = node
    app.send(f"{W}/{affordance}", data)
    events = app.wait(lambda ev: len(errors(ev, "wot")) >= 1)
    (wot,) = errors(events, "wot")
    assert wot["code"] == "invalid-event" and wot["topic"] == f"{W}/{affordance}"
    assert (wot["errors"][0]["path"], words in wot["errors"][0]["message"]) == (path, True), wot
    assert f"({path or '/'}: " in wot["message"] and "payload" not in json.dumps(wot), wot
    (envelope,) = errors(app.wait(lambda ev: len(errors(ev)) >= 1))  # the same answer, enveloped
    assert envelope["payload"]["errors"] == wot["errors"] and envelope["payload"]["topic"] == wot["topic"]
