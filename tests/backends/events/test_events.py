"""`--backend events`: schemas valid against the 2020-12 meta-schema, example events good and bad, the AsyncAPI
document's structure and references, the exposed TD accepted by our own validator, determinism, hostile text."""

from __future__ import annotations

import json
import posixpath
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

import td2adaptor
from td2adaptor.backends.events import generator as backend
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from td2adaptor.model import Model
from td2adaptor.model.events import ALL_ROBOTS, Kind, build_catalog, data_schema
from td2adaptor.model.exposed import DEFAULT_PACKET
from td2adaptor.model.wot import wot_topic
from td2adaptor.runtime.events import EventValidator
from tests.backends.events.schemawalk import subschemas, untyped
from tests.conftest import EXAMPLE, REPO
from tests.runtime.rb1 import GOAL, compile_td, rb1_catalog, rb1_model, rb1_validator

ENVELOPE = {"robot": "rb1_base_a", "id": "e1", "time": "2026-01-31T12:00:00.123Z", "source": "test"}


def tree_of(model: Model) -> dict[str, bytes]:
    """The model's folder of the events output, OUT/events/<package>/: its paths relative to the folder."""
    files = dict(backend.generate(model, GenOptions(), Diagnostics()).files)
    prefix = model.package_name + "/"
    assert all(path.startswith(prefix) for path in files), sorted(files)
    return {path[len(prefix) :]: data for path, data in files.items()}


@pytest.fixture(scope="module")
def files() -> dict[str, bytes]:
    return tree_of(rb1_model())


def doc(files: dict[str, bytes], path: str) -> Any:
    return json.loads(files[path])


def test_every_schema_is_a_valid_2020_12_schema(files: dict[str, bytes]) -> None:
    schemas = sorted(p for p in files if p.endswith(".schema.json"))
    specs = rb1_catalog().specs
    # one file per component (its events in $defs), one per robot-level event, the envelope
    components = {s.component for s in specs if s.component}
    assert schemas == sorted(
        [f"schemas/{c}.events.schema.json" for c in components]
        + ["schemas/error.schema.json", "schemas/status.schema.json", "schemas/envelope.schema.json"]
    )
    ids = set()
    for path in schemas:
        schema = doc(files, path)
        Draft202012Validator.check_schema(schema)
        assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
        assert schema["$id"].endswith("/" + path)  # the file layout mirrors the ids: relative refs resolve
        ids.add(schema["$id"])
    assert len(ids) == len(schemas)
    # every event's schema is where its reference says, once
    found = [_resolve(files, "README.md", None, s.schema_ref) for s in specs]
    assert all(isinstance(f, dict) and f["title"] == s.title for f, s in zip(found, specs, strict=True))
    defs = sum(len(doc(files, f"schemas/{c}.events.schema.json")["$defs"]) for c in components)
    assert defs == sum(1 for s in specs if s.component)


def test_one_event_per_affordance_role(files: dict[str, bytes]) -> None:
    keys = [s.key for s in rb1_catalog().specs]
    for run, query, cancel, comp in (
        ("gotoRun", "gotoQuery", "gotoCancel", "GoToComponent"),
        ("pickRun", "pickQuery", "pickCancel", "PickComponent"),
        ("placeRun", "placeQuery", "placeCancel", "PlaceComponent"),
    ):
        for key in (f"{run}.invoke", f"{run}.feedback", f"{run}.state", f"{query}.query", f"{cancel}.cancel"):
            assert f"{comp}.{key}" in keys
    assert "AvailabilityComponent.availability.property" in keys
    assert "PoseMarkerComponent.poseMarker.property" in keys
    assert "DoorComponent.door.write" in keys
    assert keys[-2:] == ["error", "status"]


def _check(key: str, event: Any) -> list[tuple[str, str]]:
    spec = next(s for s in rb1_catalog().specs if s.key == key)
    return rb1_validator().errors(spec, event)


FEEDBACK: dict[str, Any] = {
    "type": "feedback",
    "affordance": "gotoRun",
    **ENVELOPE,
    "correlation": "c",
    "mission": 4,
    "payload": {"state": "running", "terminal": False, "seq": 2, "result": "ok", "last_event": "start"},
}

STAMP = {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": "map"}
POSE = {"position": {"x": 1.0, "y": 2.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}
#: a whole ar_track_alvar AlvarMarkers message: what the robot sends has every field
MARKERS = {
    "header": STAMP,
    "markers": [{"header": STAMP, "id": 3, "confidence": 0, "pose": {"header": STAMP, "pose": POSE}}],
}
PROPERTY = {"type": "property", "affordance": "poseMarker", **ENVELOPE}

GOOD: list[tuple[str, Any]] = [
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL}),
    ("GoToComponent.gotoRun.invoke", {"type": "invoke", "affordance": "gotoRun", **ENVELOPE, "payload": GOAL}),
    ("GoToComponent.gotoRun.invoke", {"robot": ALL_ROBOTS, "correlation": "x", "payload": {"procedure": {}}}),
    ("GoToComponent.gotoQuery.query", {}),
    ("GoToComponent.gotoQuery.query", {"mission": 4, "correlation": "q"}),
    ("GoToComponent.gotoCancel.cancel", {"type": "cancel", "mission": -1}),
    ("GoToComponent.gotoRun.feedback", FEEDBACK),
    (
        "GoToComponent.gotoRun.feedback",
        {**FEEDBACK, "payload": {"state": "failed", "terminal": True, "seq": 3, "reason": "timeout", "message": "m"}},
    ),
    ("GoToComponent.gotoRun.state", {**FEEDBACK, "type": "state", "payload": {"state": "paused", "terminal": False}}),
    (
        "PoseMarkerComponent.poseMarker.property",
        {"type": "property", "affordance": "poseMarker", **ENVELOPE, "payload": MARKERS},
    ),
    ("DoorComponent.door.write", {"payload": {"data": 1.0}}),
    (
        "error",
        {
            "type": "error",
            **ENVELOPE,
            "payload": {"code": "busy", "message": "m", "errors": [{"path": "", "message": "x"}]},
        },
    ),
    ("status", {"type": "status", **ENVELOPE, "payload": {"state": "offline", "thing": "Robotnik RB-1"}}),
]

BAD: list[tuple[str, Any, str]] = [
    ("GoToComponent.gotoRun.invoke", {}, "payload"),
    ("GoToComponent.gotoRun.invoke", [], "object"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "extra": 1}, "extra"),
    ("GoToComponent.gotoRun.invoke", {"payload": {"procedure": {"goals": {}}}}, "array"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "type": "cancel"}, "invoke"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "affordance": "pickRun"}, "gotoRun"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "mission": 3}, "mission"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "robot": "a/b"}, "does not match"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "time": "yesterday"}, "does not match"),
    ("GoToComponent.gotoRun.invoke", {"payload": GOAL, "correlation": ""}, "non-empty"),
    ("GoToComponent.gotoQuery.query", {"payload": {}}, "payload"),
    ("GoToComponent.gotoQuery.query", {"mission": 1.5}, "integer"),
    ("GoToComponent.gotoRun.feedback", {**FEEDBACK, "robot": ALL_ROBOTS}, "all"),
    ("GoToComponent.gotoRun.feedback", {**FEEDBACK, "payload": {**FEEDBACK["payload"], "state": "done"}}, "done"),
    ("GoToComponent.gotoRun.feedback", {**FEEDBACK, "payload": {**FEEDBACK["payload"], "seq": 0}}, "minimum"),
    ("GoToComponent.gotoRun.feedback", {k: v for k, v in FEEDBACK.items() if k != "id"}, "'id'"),
    ("GoToComponent.gotoRun.state", {**FEEDBACK, "type": "state"}, "seq"),
    ("DoorComponent.door.write", {"payload": {"data": "open"}}, "number"),
    # payloads the ROS message cannot hold are refused where they arrive (issue 11)
    ("DoorComponent.door.write", {"payload": {"linear": {"x": "fast"}}}, "'linear' was unexpected"),
    ("PickComponent.pickRun.invoke", {"payload": {"nope": 1}}, "'nope' was unexpected"),
    ("PickComponent.pickRun.invoke", {"payload": {"markerID": 2}}, "'markerID' was unexpected"),
    ("PickComponent.pickRun.invoke", {"payload": {"procedure": {"pick_frame_id": 2}}}, "not of type 'string'"),
    ("GoToComponent.gotoRun.invoke", {"payload": {"procedure": {"goals": [{"pose": {"x": "fast"}}]}}}, "number"),
    # what the robot sends is a whole message, nothing more
    ("PoseMarkerComponent.poseMarker.property", {**PROPERTY, "payload": {"markers": []}}, "'header' is a required"),
    ("PoseMarkerComponent.poseMarker.property", {**PROPERTY, "payload": {**MARKERS, "x": 1}}, "'x' was unexpected"),
    (
        "PoseMarkerComponent.poseMarker.property",
        {**PROPERTY, "payload": {**MARKERS, "header": {"stamp": {"secs": 1, "nsecs": 2}, "frame_id": "m"}}},
        "'sec' is a required",
    ),
    ("error", {"type": "error", **ENVELOPE, "payload": {"code": "oops", "message": "m"}}, "oops"),
    ("status", {"type": "status", **ENVELOPE, "payload": {"state": "sleepy"}}, "sleepy"),
]


@pytest.mark.parametrize(("key", "event"), GOOD, ids=[f"{k}-{i}" for i, (k, _) in enumerate(GOOD)])
def test_good_events_validate(key: str, event: Any) -> None:
    assert _check(key, event) == []


@pytest.mark.parametrize(("key", "event", "why"), BAD, ids=[f"{k}-{i}" for i, (k, _, _) in enumerate(BAD)])
def test_bad_events_are_refused(key: str, event: Any, why: str) -> None:
    errors = _check(key, event)
    assert errors, event
    assert any(why in message or why in path for path, message in errors), errors


def test_generated_schema_files_validate_like_the_runtime(files: dict[str, bytes], tmp_path: Path) -> None:
    """The files on their own (a consumer's registry built from them) give the same verdicts."""
    from referencing import Registry, Resource

    schemas = {p: doc(files, p) for p in files if p.endswith(".schema.json")}
    registry = Registry().with_resources((s["$id"], Resource.from_contents(s)) for s in schemas.values())
    spec = next(s for s in rb1_catalog().specs if s.key == "GoToComponent.gotoRun.feedback")
    # a consumer refers to the event by the file's id and the pointer into it, as the AsyncAPI document does
    uri = doc(files, spec.schema_file)["$id"] + "#" + spec.schema_ref.partition("#")[2]
    validator = Draft202012Validator({"$ref": uri}, registry=registry)
    assert validator.is_valid(FEEDBACK)
    assert not validator.is_valid({**FEEDBACK, "payload": {"state": "running"}})
    assert not validator.is_valid({**FEEDBACK, "robot": ALL_ROBOTS})  # from the embedded schema
    assert not validator.is_valid({**FEEDBACK, "time": "yesterday"})  # from the envelope, via its relative $ref
    status = Draft202012Validator(schemas["schemas/status.schema.json"], registry=registry)
    assert status.is_valid({"type": "status", **ENVELOPE, "payload": {"state": "online"}})
    assert not status.is_valid({"type": "status", **ENVELOPE, "time": "now", "payload": {"state": "online"}})


def _resolve(files: dict[str, bytes], base: str, root: Any, ref: str) -> Any:
    path, _, fragment = ref.partition("#")
    target = root if not path else doc(files, posixpath.normpath(posixpath.join(posixpath.dirname(base), path)))
    for part in [p for p in fragment.split("/") if p]:
        target = target[part.replace("~1", "/").replace("~0", "~")]
    return target


def _refs(node: Any) -> list[str]:
    if isinstance(node, dict):
        out = [node["$ref"]] if isinstance(node.get("$ref"), str) else []
        return out + [r for v in node.values() for r in _refs(v)]
    if isinstance(node, list):
        return [r for v in node for r in _refs(v)]
    return []


def test_asyncapi_document(files: dict[str, bytes]) -> None:
    api = doc(files, "asyncapi.json")
    assert api["asyncapi"] == "3.1.0"
    assert api["info"]["title"] and api["info"]["version"]
    assert api["servers"]["broker"]["protocol"] == "mqtt"
    assert set(api["servers"]["broker"]["host"].strip("{}").split(":")) <= set(api["servers"]["broker"]["variables"])
    for ref in _refs(api):  # every reference resolves, in the document or to a schema file
        assert _resolve(files, "asyncapi.json", api, ref) is not None, ref
    for key, channel in api["channels"].items():
        assert channel["address"].startswith("td2adaptor/") and channel["messages"]
        for param in channel.get("parameters", {}):
            assert "{" + param + "}" in channel["address"]
        assert "{" not in channel["address"] or channel.get("parameters"), key
    for key, op in api["operations"].items():
        assert op["action"] in ("send", "receive")
        channel_ref = op["channel"]["$ref"]
        channel = _resolve(files, "asyncapi.json", api, channel_ref)
        for m in op["messages"]:  # operation messages must be the channel's own
            assert m["$ref"].startswith(channel_ref + "/messages/"), key
        if "reply" in op:
            assert op["action"] == "receive" and op["reply"]["channel"]["$ref"].startswith("#/channels/")
        assert channel
    for message in api["components"]["messages"].values():
        payload = message["payload"]
        assert payload["schemaFormat"] == "application/schema+json;version=draft-07"  # what AsyncAPI tools check
        schema = _resolve(files, "asyncapi.json", api, payload["schema"]["$ref"])
        Draft202012Validator.check_schema(schema)
        assert schema["title"] == message["title"]
    # every inbound event has its robot channel and the all-robots channel; outbound ones only the first
    addresses = {c["address"] for c in api["channels"].values()}
    for spec in rb1_catalog().specs:
        assert spec.topic("{robot}") in addresses
        assert (spec.topic(ALL_ROBOTS) in addresses) == spec.kind.inbound
    receive = {k for k, o in api["operations"].items() if o["action"] == "receive"}
    assert "receive.GoToComponent.gotoRun.invoke.all" in receive


ROBOT = "rb1_base_a"
BROKER = "mqtt://127.0.0.1:1883"
TM_VALUES = {"robotName": ROBOT, "mqttBroker": BROKER}
BINDINGS = REPO.parent / "shared" / "wot" / "bindings"


def robot_td() -> dict[str, Any]:
    return backend.exposed_td(rb1_model(), robot=ROBOT, broker=BROKER)


def test_exposed_td_passes_our_validator(files: dict[str, bytes], tmp_path: Path) -> None:
    for name, td, values in (
        ("model", doc(files, "td.mqtt.json"), TM_VALUES),  # the fleet's Thing Model, instantiated
        ("robot", robot_td(), None),
    ):
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(td), encoding="utf-8")
        result = td2adaptor.compile(path, values=values)
        errors = [d for d in result.diagnostics if d.severity is Severity.ERROR]
        assert not errors, [(d.code, d.message, d.pointer) for d in errors]
        warnings = {d.code for d in result.diagnostics}
        assert warnings <= {"ROS400", "TM302"}, warnings  # no ROS binding left: expected, it is the MQTT view


def _official(name: str) -> Any:
    """The W3C schema: from ../shared/wot, else the pinned npm package (tests/wot_corpus.py), else a skip."""
    from tests.wot_corpus import official_json

    return official_json(name)


def _errors(schema: Any, instance: Any, registry: Any = None) -> list[str]:
    from jsonschema import Draft7Validator, FormatChecker

    kw = {} if registry is None else {"registry": registry}
    validator = Draft7Validator(schema, format_checker=FormatChecker(), **kw)
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message[:200]}" for e in validator.iter_errors(instance)]


def test_robot_td_passes_the_official_td_schema_and_the_model_the_tm_schema(files: dict[str, bytes]) -> None:
    assert _errors(_official("td-schema-v1.1.json"), robot_td()) == []
    model = doc(files, "td.mqtt.json")
    assert model["@type"] == "tm:ThingModel"
    assert _errors(_official("tm-schema-v1.1.json"), model) == []


def test_robot_td_passes_the_w3c_mqtt_binding_schema() -> None:
    path = BINDINGS / "mqtt.schema.json"
    if not path.is_file():
        pytest.skip(f"the W3C MQTT binding template's schema is not in {BINDINGS}")
    from referencing import Registry, Resource
    from referencing.jsonschema import DRAFT7

    binding = json.loads(path.read_text(encoding="utf-8"))
    td_uri = binding["anyOf"][0]["$ref"]  # the official TD schema by URL: resolved offline
    registry = Registry().with_resource(td_uri, Resource.from_contents(_official("td-schema-v1.1.json"), DRAFT7))
    assert _errors(binding, robot_td(), registry) == []
    # the schema does check the binding's vocabulary: the old values are refused
    old = robot_td()
    old["actions"]["gotoRun"]["forms"][0]["mqv:controlPacket"] = "mqv:publish"
    old["properties"]["poseMarker"]["forms"][0]["mqv:qos"] = 1
    refused = _errors(binding, old, registry)
    assert {e.rpartition(": ")[0].rpartition(": ")[0] or e.partition(": ")[0] for e in refused} == {
        "actions/gotoRun/forms/0/mqv:controlPacket",
        "properties/poseMarker/forms/0/mqv:qos",
    }


def test_robot_td_for_ros1_names_time_as_ros1_does() -> None:
    ros1 = backend.exposed_td(rb1_model(), build_catalog(rb1_model(), "ros1"), robot=ROBOT, broker=BROKER)
    text = json.dumps(ros1)
    assert '"secs"' in text and '"nsecs"' in text and '"nanosec"' not in text
    text = json.dumps(robot_td())
    assert '"sec"' in text and '"nanosec"' in text and '"nsecs"' not in text


def _forms(td: dict[str, Any]) -> list[dict[str, Any]]:
    return [f for section in ("properties", "actions", "events") for a in td[section].values() for f in a["forms"]]


def test_exposed_td_forms(files: dict[str, bytes]) -> None:
    td = robot_td()
    assert {"mqv": "http://www.example.org/mqtt-binding#"} in td["@context"]
    assert td["@type"] == "Thing" and td["id"] == f"urn:dev:wot:robotnik:rb1:{ROBOT}"
    assert "{{" not in json.dumps(td)
    # every affordance on its WoT topic (the data alone); the status event on its envelope topic
    topics = {wot_topic(s, ROBOT) or s.topic(ROBOT) for s in rb1_catalog().specs}
    seen = set()
    for form in _forms(td):
        ops = [form["op"]] if isinstance(form["op"], str) else form["op"]
        # the W3C MQTT binding's default mapping gives each operation its control packet: stated only for the
        # operations it maps to nothing; the content type is TD 1.1's default (application/json)
        assert ("mqv:controlPacket" in form) == (
            ops in (["queryaction"], ["cancelaction"])
        ) and "contentType" not in form
        packets = {form.get("mqv:controlPacket") or DEFAULT_PACKET[op] for op in ops}
        assert packets in ({"publish"}, {"subscribe", "unsubscribe"})  # one form for a subscription and its end
        publish = packets == {"publish"}
        topic = form["mqv:topic"] if publish else form["mqv:filter"]
        assert ("mqv:topic" in form) == publish and ("mqv:filter" in form) != publish
        assert form["href"] == f"{BROKER}/{topic}"  # node-wot 0.8 reads the topic from the href path
        assert form["mqv:qos"] == "1"  # the runtime's QoS 1
        seen.add(topic)
    assert seen == topics
    goto = td["actions"]["gotoRun"]
    assert [f["op"] for f in goto["forms"]] == ["invokeaction", "queryaction", "cancelaction"]
    assert [f.get("mqv:controlPacket") for f in goto["forms"]] == [None, "publish", "publish"]
    assert all("mqv:retain" not in f for f in goto["forms"])
    assert [f["mqv:topic"] for f in goto["forms"]] == [
        f"td2adaptor/{ROBOT}/wot-thing/GoToComponent/{name}" for name in ("gotoRun", "gotoQuery", "gotoCancel")
    ]
    # the input is the goal's own fields (no envelope), plus the optional correlationId
    assert list(goto["input"]["properties"]) == ["procedure", "correlationId"] and "required" not in goto["input"]
    assert goto["input"]["properties"]["procedure"]["type"] == "object"
    query = td["actions"]["gotoQuery"]["input"]
    assert set(query["properties"]) == {"mission", "correlationId"}
    availability = td["properties"]["availability"]
    assert availability["forms"][0]["op"] == ["readproperty", "observeproperty", "unobserveproperty"]
    assert availability["observable"] and availability["readOnly"] and "writeOnly" not in availability
    assert availability["forms"][0]["mqv:retain"] is True  # property values are retained, as is the status
    assert td["events"]["status"]["forms"][0]["mqv:retain"] is True
    assert "mqv:retain" not in td["events"]["gotoRunFeedback"]["forms"][0]
    assert td["properties"]["door"]["writeOnly"] is True and "readOnly" not in td["properties"]["door"]
    assert td["properties"]["door"]["forms"][0]["mqv:topic"] == f"td2adaptor/{ROBOT}/wot-thing/DoorComponent/door"
    assert set(td["properties"]["door"]["properties"]) == {"data"}  # the value itself
    assert "payload" not in td["properties"]["poseMarker"]["properties"]
    feedback = td["events"]["gotoRunFeedback"]
    assert [f["op"] for f in feedback["forms"]] == [["subscribeevent", "unsubscribeevent"]]
    assert feedback["data"]["properties"]["state"]["enum"][-1] == "cancelled"
    assert {"correlationId", "mission", "terminal", "seq"} <= set(feedback["data"]["properties"])
    assert set(td["events"]) == {
        f"{run}{kind}" for run in ("gotoRun", "pickRun", "placeRun") for kind in ("Feedback", "State")
    } | {"error", "status"}
    # the status keeps its envelope, and the TD says so: what it describes is what travels there
    assert set(td["events"]["status"]["data"]["properties"]) >= {"type", "robot", "id", "time", "payload"}
    # the fleet's model: the same with placeholders for the robot and the broker
    model = doc(files, "td.mqtt.json")
    text = json.dumps(model).replace("{{robotName}}", ROBOT).replace("{{mqttBroker}}", BROKER)
    instantiated = json.loads(text)
    assert _forms(instantiated) == _forms(td)
    assert instantiated["id"] == td["id"]


def test_property_qos_0_is_what_the_observe_forms_say() -> None:
    """`property_qos: 0` (high-rate sensor streams): the property forms say QoS 0, as the events travel; every
    other form keeps QoS 1, and the default TD is unchanged."""
    td = backend.exposed_td(rb1_model(), robot=ROBOT, broker=BROKER, property_qos=0)
    default = robot_td()
    # the robot's presence is its status event, which always travels at QoS 1
    assert td["properties"]["presence"] == default["properties"]["presence"]
    for name, prop in td["properties"].items():
        for form, before in zip(prop["forms"], default["properties"][name]["forms"], strict=True):
            observe = "mqv:filter" in form and name != "presence"
            assert form.get("mqv:qos") == ("0" if observe else before.get("mqv:qos")), (name, form)
    assert any(f.get("mqv:qos") == "0" for p in td["properties"].values() for f in p["forms"])
    others = [f for s in ("actions", "events") for a in td[s].values() for f in a["forms"]]
    assert others == [f for s in ("actions", "events") for a in default[s].values() for f in a["forms"]]


def test_hrefs_percent_encode_the_topic() -> None:
    assert backend.topic_href("mqtt://h:1", "a b/c%d/é") == "mqtt://h:1/a%20b/c%25d/%C3%A9"
    assert backend.topic_href("mqtt://h:1", "t/{{robotName}}/x", model=True) == "mqtt://h:1/t/{{robotName}}/x"
    td = backend.exposed_td(rb1_model(), robot="r.1-a", broker="mqtts://[::1]:8883", root="my root")
    forms = _forms(td)
    assert forms[0]["href"].startswith("mqtts://[::1]:8883/my%20root/r.1-a/")
    assert forms[0]["mqv:filter"].startswith("my root/r.1-a/")


def test_every_const_or_enum_has_a_type(files: dict[str, bytes]) -> None:
    """wotpy 0.18 refuses a data schema with `const` or `enum` and no `type` (ValueError: Unknown type: None)."""
    schemas = {p: doc(files, p) for p in files if p.endswith(".schema.json")}
    checked = 0
    for path, schema in schemas.items():
        assert untyped(schema) == [], path
        checked += sum(1 for _, s in subschemas(schema) if "const" in s or "enum" in s)
    for td in (robot_td(), doc(files, "td.mqtt.json")):
        for section in ("properties", "actions", "events"):
            for name, affordance in td[section].items():
                assert untyped(affordance) == [], f"{section}/{name}"
                checked += sum(1 for _, s in subschemas(affordance) if "const" in s or "enum" in s)
    assert checked > 50


def test_a_td_schema_without_types_gets_them() -> None:
    schema = {
        "type": "object",
        "properties": {
            "mode": {"enum": ["a", "b"]},
            "n": {"enum": [1, 2.5]},
            "one": {"const": True},
            "mixed": {"enum": ["x", 1, None]},
            "typed": {"type": "string", "enum": ["kept"]},
        },
    }
    out = data_schema(schema)["properties"]
    assert out["mode"] == {"enum": ["a", "b"], "type": "string"}
    assert out["n"]["type"] == "number" and out["one"]["type"] == "boolean"
    assert out["mixed"] == {
        "anyOf": [{"type": "string", "enum": ["x"]}, {"type": "integer", "enum": [1]}, {"type": "null", "enum": [None]}]
    }
    assert out["typed"] == {"type": "string", "enum": ["kept"]}
    validator = Draft202012Validator(data_schema(schema))
    assert validator.is_valid({"mixed": None}) and validator.is_valid({"mixed": 1})
    assert not validator.is_valid({"mixed": "1"})


def test_generation_is_deterministic(files: dict[str, bytes]) -> None:
    again = tree_of(compile_td(EXAMPLE / "td.json"))
    assert again == files


def test_hostile_td_text_stays_data(tmp_path: Path) -> None:
    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    evil = 'Evil | RB-1\n| injected | row |\n<script>alert(1)</script> `code` "quote" \\ \u2028 end'
    td["title"] = evil
    td["description"] = evil
    td["actions"]["gotoRun"]["title"] = evil
    td["actions"]["gotoRun"]["input"]["properties"]["procedure"]["$ref"] = "http://example.invalid/x.json"
    td["actions"]["gotoRun"]["input"]["properties"]["procedure"]["$id"] = "http://example.invalid/owned"
    path = tmp_path / "evil.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    result = td2adaptor.compile(path, interfaces=[EXAMPLE / "interfaces"])
    assert result.model is not None
    files = tree_of(result.model)
    readme = files["README.md"].decode()
    assert "| injected | row |" not in readme and "<script>" not in readme
    assert all(line.count("|") in (0, 5) for line in readme.splitlines() if line.startswith("|"))
    for path_, data in files.items():
        if path_.endswith(".json"):
            parsed = json.loads(data)
            assert "example.invalid" not in json.dumps(parsed.get("properties", {}).get("payload", {}))
    api = json.loads(files["asyncapi.json"])
    assert api["info"]["title"] == f"{evil} events"  # JSON escaping keeps the text as it was
    exposed = tmp_path / "exposed.json"
    exposed.write_bytes(files["td.mqtt.json"])
    diagnostics = td2adaptor.compile(exposed, values=TM_VALUES).diagnostics
    assert not [d for d in diagnostics if d.severity is Severity.ERROR]
    # the runtime's validators never look anything up
    EventValidator(build_catalog(result.model))


def test_data_schema_keeps_data_and_drops_references() -> None:
    schema = {
        "type": "object",
        "$id": "x",
        "@type": "saref:Thing",
        "properties": {"$odd": {"$ref": "http://x", "type": "string"}, "n": {"enum": [{"$ref": "kept as data"}]}},
        "items": [1],
    }
    out = data_schema(schema)
    assert out == {
        "type": "object",
        "properties": {"$odd": {"type": "string"}, "n": {"enum": [{"$ref": "kept as data"}], "type": "object"}},
        "items": [1],
    }


def test_routes_match_topics() -> None:
    catalog = rb1_catalog()
    for spec in catalog.inbound():
        for robot in ("rb1_base_a", ALL_ROBOTS):
            assert catalog.route(spec.topic(robot)) == (spec, robot)
    for spec in catalog.specs:
        if not spec.kind.inbound:
            assert catalog.route(spec.topic("rb1_base_a")) is None
    assert catalog.route("td2adaptor/r/DoorComponent/door") is None
    assert catalog.route("other/r/GoToComponent/gotoRun") is None
    assert catalog.route("td2adaptor/r/GoToComponent/gotoRun/extra") is None


def test_models_without_ros_types_still_get_schemas() -> None:
    model = rb1_model()
    comp = model.components[0]
    bare = replace(comp, services=tuple(replace(s, input_schema=None) for s in comp.services))
    catalog = build_catalog(replace(model, components=(bare, *model.components[1:])))
    invoke = catalog.find(Kind.INVOKE, "gotoRun")
    payload = invoke.schema["properties"]["payload"]
    assert payload["properties"]["procedure"]["properties"]["goals"]["type"] == "array"  # from GoToPetition
    Draft202012Validator.check_schema(invoke.schema)


def test_components_named_like_robot_level_files_do_not_collide() -> None:
    model = rb1_model()
    renamed = tuple(replace(c, name=n) for c, n in zip(model.components, ("envelope", "error", "status"), strict=False))
    model = replace(model, components=(*renamed, *model.components[3:]))
    files = tree_of(model)
    assert {"schemas/envelope.schema.json", "schemas/error.schema.json", "schemas/status.schema.json"} <= set(files)
    assert {"schemas/envelope.events.schema.json", "schemas/error.events.schema.json"} <= set(files)
    envelope = doc(files, "schemas/envelope.schema.json")
    assert envelope["properties"]["payload"]["description"] == "Event-specific content."
    validator = EventValidator(build_catalog(model))
    spec = build_catalog(model).find(Kind.INVOKE, "gotoRun")
    assert validator.errors(spec, {"payload": GOAL}) == []


_json_data = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=6), children, max_size=3),
    max_leaves=12,
)


def _floats(value: Any) -> bool:
    if isinstance(value, float):
        return True
    if isinstance(value, dict):
        return any(_floats(v) for v in value.values())
    return isinstance(value, list) and any(_floats(v) for v in value)


@settings(max_examples=300, deadline=None)
@given(_json_data)
def test_dump_is_the_standard_library_layout(value: Any) -> None:
    # orjson (fast path) and json.dumps (what it refuses, e.g. integers beyond 64 bits) must agree on layout;
    # floats only differ in how an exponent is spelled (1e-05 / 0.00001), both exact
    text = backend.dump(value)
    assert json.loads(text) == value
    if not _floats(value):
        assert text == json.dumps(value, indent=2, ensure_ascii=False) + "\n"
    assert backend.dump(value) == text


def robot_block(rules: list[str], robot: str) -> list[str]:
    """The rules of `robot`'s user block (up to the next user)."""
    start = rules.index(f"user {robot}") + 1
    end = next(i for i in range(start, len(rules)) if rules[i].startswith("user "))
    return rules[start:end]


def test_the_broker_acl_names_each_robots_topics_and_refuses_ids_that_would_open_others() -> None:
    """Issue 30, item 10: one `user` block per robot of `events.robots`, its topics written out (no `pattern`
    with %u, which mosquitto fills with a user name as it is, '/' included); an id with '/', '+' or '#', or any
    other that is no robot id, is refused (GEN860) rather than written into the ACL."""
    model = rb1_model()

    def acl(robots: Any) -> tuple[str, list[str]]:
        diags = Diagnostics()
        tree = backend.generate(model, GenOptions(extra=(("events.robots", robots),)), diags)
        return tree.files[f"{model.package_name}/mosquitto.acl"].decode(), [f"{d.code}: {d.message}" for d in diags]

    for robots in (["rb1_a", "rb1_b"], "rb1_a, rb1_b"):  # a list (TOML, JSON) or one string with commas
        text, said = acl(robots)
        rules = [line for line in text.splitlines() if line and not line.startswith("#")]
        assert said == [] and not [r for r in rules if "%" in r or r.startswith("pattern")]
        users = [r for r in rules if r.startswith("user ")]
        assert users == ["user rb1_a", "user rb1_b", "user fleet-node", "user fleet-admin", "user application"]
        block = rules[rules.index("user rb1_a") + 1 : rules.index("user rb1_b")]
        # and the fleet's admin requests (docs/fleet.md), at a level no robot id can be
        fleet = f"td2adaptor/.fleet/{model.package_name}"
        assert f"topic write {fleet}/answer" in block and f"topic read {fleet}/request" in block
        # and what a process of `run --share` needs (node/share.py): its member record, beats, admitted
        # entries, and every robot's status (read only: is the robot free?)
        for level in ("members/+", "beats/+", "admitted/+/+"):
            assert f"topic write {fleet}/{level}" in block, level
        assert "topic read td2adaptor/+/status" in block
        assert [r for r in block if r.startswith("topic write") and "/+" in r and f" {fleet}/" not in r] == []
        block = [r for r in block if f" {fleet}/" not in r and r != "topic read td2adaptor/+/status"]
        assert "topic write td2adaptor/rb1_a/wot-thing/GoToComponent/gotoRun/feedback" in block
        # its commands through filters that also match topics no event is defined on (answered unknown-topic)
        assert "topic read td2adaptor/rb1_a/+/+" in block and "topic read td2adaptor/rb1_a/wot-thing/+/+" in block
        assert "topic read td2adaptor/rb1_a/DoorComponent/+/write" in block
        assert all("/rb1_a/" in r or "/all/" in r for r in block), block
        # the process that serves robots not known in advance (run --discover, admin adds): a node block for any
        node = rules[rules.index("user fleet-node") + 1 : rules.index("user fleet-admin")]
        assert node == list(dict.fromkeys(r.replace("/rb1_a/", "/+/") for r in robot_block(rules, "rb1_a"))), node
    for bad in ("sa_a/wot-thing", "+", "#", "a+b", ALL_ROBOTS, "", 7):
        _, said = acl(["rb1_a", bad])
        assert len(said) == 1 and said[0].startswith("GEN860") and "is not a robot id" in said[0], (bad, said)
    assert acl(["rb1_a", "rb1_a"])[1] == ["GEN860: events backend: events.robots names 'rb1_a' twice"]
    for user in ("fleet-node", "fleet-admin", "application"):  # a robot's block would add to that user's
        _, said = acl(["rb1_a", user])
        assert len(said) == 1 and "a user the broker ACL has a block of its own for" in said[0], (user, said)
    assert acl({"rb1_a": 1})[1] == ["GEN860: events backend: events.robots must be a list of robot ids"]
    diags = Diagnostics()
    backend.generate(model, GenOptions(extra=(("events.robot", ["rb1_a"]),)), diags)
    assert [d.code for d in diags] == ["GEN860"]
    # without robot ids, one block for the stand-in <robot>, which no robot id can be: it grants a robot nothing
    text, said = acl([])
    assert said == ["GEN860: events backend: events.robots must be a list of robot ids"]
    text = tree_of(model)["mosquitto.acl"].decode()
    assert "\nuser <robot>\n" in text and "topic write td2adaptor/<robot>/status" in text


def test_the_broker_acl_lets_the_fleet_admin_ask_and_the_nodes_answer_and_refuses_a_bad_fleet_name() -> None:
    """Issue 32: the fleet's admin requests (`events.fleet`, default the package name): the `fleet-admin` user
    writes requests and reads answers, each node the other way round; a fleet name that is no single topic
    level is refused (GEN860)."""
    model = rb1_model()

    def acl(fleet: Any) -> tuple[list[str], list[str]]:
        diags = Diagnostics()
        extra = (("events.robots", ["rb1_a"]), ("events.fleet", fleet))
        tree = backend.generate(model, GenOptions(extra=extra), diags)
        text = tree.files[f"{model.package_name}/mosquitto.acl"].decode()
        return [r for r in text.splitlines() if r and not r.startswith("#")], [f"{d.code}: {d.message}" for d in diags]

    rules, said = acl("site_7")
    assert said == []
    admin = rules[rules.index("user fleet-admin") + 1 : rules.index("user application")]
    assert admin == ["topic write td2adaptor/.fleet/site_7/request", "topic read td2adaptor/.fleet/site_7/answer"]
    node = rules[rules.index("user rb1_a") + 1 : rules.index("user fleet-admin")]
    assert "topic read td2adaptor/.fleet/site_7/request" in node
    assert "topic write td2adaptor/.fleet/site_7/answer" in node
    for bad in ("a/b", "+", "#", ALL_ROBOTS, "", 7):
        _, said = acl(bad)
        assert len(said) == 1 and said[0].startswith("GEN860") and "is not a fleet name" in said[0], (bad, said)
