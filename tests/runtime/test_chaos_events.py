"""Every event that reaches a topic the edge node subscribes to is answered, whatever it holds (issue 30, item 5).

Five thousand malformed events, each a valid one of the simulated RB-1 with exactly one thing wrong put in at
a random place (a number no double holds, a lone surrogate in a string or a member name, nesting up to 3000
deep, a member of the wrong type or unknown, an event too large, bytes that are no JSON), on the envelope
topics and the WoT topics of every inbound affordance, thrown at the engine on the in-process bus: each gets
exactly one error event (and its WoT form), none runs, the robot is never called, and the node still serves.
Seeded, so a failure can be replayed.
"""

from __future__ import annotations

import json
import random
import time
from typing import Any

from td2adaptor.model.events import EventSpec, Kind
from td2adaptor.model.wot import CORRELATION, WOT_LEVEL, wot_topic
from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.edge import Recorder
from tests.runtime.rb1 import GOAL, check_outbound, rb1_catalog, rb1_model, sim, terminal

ROBOT = "rb1_chaos"
T = f"td2adaptor/{ROBOT}"
COUNT = 5000
MAX_BYTES = 8192
SEED = 30
SLOT = "@@slot@@"  # a string the poison's text replaces in the event's JSON

NON_FINITE = ["1e400", "-1e400", "1e999", "-2.5e308", "NaN", "Infinity", "-Infinity", "1" + "0" * 400]
NOT_TEXT = ['"\\ud800"', '"x\\udc00y"', '"\\udbff\\udbff"', '"ok\\udfff"']


def payload_of(spec: EventSpec) -> dict[str, Any]:
    """A valid payload (the WoT data) of `spec`'s inbound event."""
    if spec.kind is Kind.WRITE:
        return {"data": 1.0}
    if spec.kind is Kind.INVOKE:
        return {"gotoRun": GOAL, "pickRun": {"procedure": {"pick_frame_id": "cart3"}}}.get(spec.affordance or "", {})
    return {}


def containers(value: Any) -> list[dict[str, Any] | list[Any]]:
    """Every object and array in `value` (where a poison can go)."""
    out: list[dict[str, Any] | list[Any]] = []
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            out.append(item)
            stack.extend(item.values())
        elif isinstance(item, list):
            out.append(item)
            stack.extend(item)
    return out


def poisoned(rng: random.Random, data: dict[str, Any]) -> bytes:
    """`data` with one thing no event may hold (or no event of this kind) put in at a random place."""
    kind = rng.choice(["number", "text", "name", "deep", "type", "unknown", "large", "bytes"])
    if kind == "bytes":
        return rng.choice([b"\xff\xfe\x00", b'{"payload": {', b"\x00" * rng.randint(1, 50), rng.randbytes(40)])
    if kind == "large":
        return json.dumps({**data, "pad": "x" * (MAX_BYTES + 10)}).encode()
    where: Any = rng.choice(containers(data))
    objects = [c for c in containers(data) if isinstance(c, dict)]
    if kind == "type" and isinstance(where, dict) and where:  # a member of another JSON type
        key = rng.choice(list(where))
        old = where[key]
        where[key] = [1] if isinstance(old, str) else "text" if not isinstance(old, (dict, list)) else 7
        return json.dumps(data).encode()
    if kind in ("type", "unknown"):  # an object member no schema has
        rng.choice(objects)["zz_unknown"] = 1
        return json.dumps(data).encode()
    if kind == "name":
        rng.choice(objects)[SLOT] = 1
        return json.dumps(data).replace(f'"{SLOT}"', rng.choice(NOT_TEXT)).encode()
    if isinstance(where, dict):
        where[rng.choice([*where, "zz"])] = SLOT  # replaces a member or adds one
    else:
        where.append(SLOT)
    if kind == "number":
        text = rng.choice(NON_FINITE)
    elif kind == "text":
        text = rng.choice(NOT_TEXT)
    else:
        depth = rng.randint(65, 3000)
        text = "[" * depth + "]" * depth
    return json.dumps(data).replace(f'"{SLOT}"', text).encode()


def events(rng: random.Random) -> list[tuple[str, bytes]]:
    catalog = rb1_catalog()
    out = []
    for i in range(COUNT):
        spec = rng.choice(list(catalog.inbound()))
        correlation = f"chaos-{i}"
        if rng.random() < 0.5:
            topic = wot_topic(spec, ROBOT)
            assert topic is not None and f"/{WOT_LEVEL}/" in topic
            data: dict[str, Any] = dict(payload_of(spec))
            if spec.kind is not Kind.WRITE:
                data[CORRELATION] = correlation
        else:
            topic = spec.topic(ROBOT)
            data = {"id": f"id-{i}", "correlation": correlation, "source": "chaos", "payload": payload_of(spec)}
            if spec.kind in (Kind.QUERY, Kind.CANCEL):
                del data["payload"]
                data["mission"] = 3
        out.append((topic, poisoned(rng, json.loads(json.dumps(data)))))
    return out


def test_thousands_of_malformed_events_each_get_exactly_one_answer() -> None:
    broker = LocalBroker()
    model = rb1_model()
    robot = sim(0.1)
    app = Recorder(broker, [f"{T}/error", f"{T}/{WOT_LEVEL}/error", f"{T}/+/+/feedback", f"{T}/+/+/state"])
    config = RuntimeConfig(robot=ROBOT, poll_period=0.02, property_period=0, max_event_bytes=MAX_BYTES, state_dir="")
    engine = serve(model, SimPort(model, robot), config, broker=broker)
    sent = events(random.Random(SEED))
    wot_error = f"{T}/{WOT_LEVEL}/error"
    try:
        begin = time.monotonic()
        for topic, raw in sent:
            app.send(topic, raw)
        # the WoT consumers are answered about the WoT messages only (no WoT consumer sent the envelope events)
        on_wot = sum(1 for topic, _ in sent if topic.startswith(f"{T}/{WOT_LEVEL}/"))
        app.wait(lambda ev: sum(1 for t, _ in ev if t == f"{T}/error") >= COUNT, timeout=30)
        app.wait(lambda ev: sum(1 for t, _ in ev if t == wot_error) >= on_wot, timeout=10)
        elapsed = time.monotonic() - begin
        time.sleep(0.2)  # an answer too many would come now
        with app.cond:
            answers = [e for t, e in app.events if t == f"{T}/error"]
            wot = [e for t, e in app.events if t == wot_error]
            others = [(t, e) for t, e in app.events if t not in (f"{T}/error", wot_error)]
        assert len(answers) == COUNT and len(wot) == on_wot and others == []  # one each, and nothing ran
        assert 0 < on_wot < COUNT and all(e["topic"].startswith(f"{T}/{WOT_LEVEL}/") for e in wot)
        codes = {e["payload"]["code"] for e in answers}
        assert codes == {"invalid-event", "invalid-json", "too-large"}, codes
        correlations = [e["correlation"] for e in answers if "correlation" in e]
        assert len(correlations) == len(set(correlations)) > COUNT // 4  # never two answers to one event
        assert all(c.startswith("chaos-") for c in correlations)
        assert engine.stats["invalid"] == COUNT and engine.stats["in"] == COUNT
        assert robot.next_id == 0 and robot.door_command is None  # the robot was never called
        # still serving
        app.send(f"{T}/GoToComponent/gotoRun", json.dumps({"correlation": "alive", "payload": GOAL}).encode())
        app.wait(terminal("feedback", "alive"))
        print(f"{COUNT} malformed events, each answered once, in {elapsed:.1f} s")
    finally:
        engine.stop()
        app.close()
    check_outbound(app.events)
