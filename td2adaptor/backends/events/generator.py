"""`--backend events`: the event contract of an adaptor, for applications that talk to robots over a bus.

Writes, under OUT/events/<package>/ (one folder per adaptor package, so the robots of one system generate
into one output side by side):

* `schemas/<Component>.events.schema.json`: JSON Schema 2020-12 of every event of a component, each under
  `$defs/<affordance>.<kind>` (see `td2adaptor.model.events` for the topic scheme); `schemas/error.schema.json` and
  `schemas/status.schema.json` for the robot-level events; all refer to `schemas/envelope.schema.json` for
  the shared fields. Every `$id` is `https://td2adaptor.dev/events/<package>/schemas/<file>`: the layout of
  OUT/events/ mirrors the ids, so relative references resolve between the files and no two packages share one;
* `asyncapi.json`: an AsyncAPI 3.0 document (MQTT channels, operations, messages referring to the schemas);
* `td.mqtt.json`: the Thing Model of the robots' exposed Thing Descriptions: the same Thing with W3C MQTT
  binding forms (`mqv:`, the topic also in the href path), so a standard WoT consumer can invoke the actions,
  observe the properties and subscribe to the feedback; `{{robotName}}` stands for the robot id and
  `{{mqttBroker}}` for the broker URL. `td2adaptor expose` writes the TD of one robot and `td2adaptor run`
  publishes it, retained, on `td2adaptor/<robot>/td`;
* `README.md`: the topic table.

and, once all TDs are generated (`finish`), OUT/events/README.md: the packages, with links to their contracts,
and what the adaptors of one system share (the broker, the topic tree, the robot ids).

Invoke payloads follow the TD's input schema (the contract the Thing publishes, cross-checked against the ROS
request type at validation time); where a TD gives none, the ROS request type's schema (`msgschema`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any
from urllib.parse import quote

import orjson

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.frontend.terms import DATA_SCHEMA
from td2adaptor.generation import textsafe as ts
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.generation.templating import environment
from td2adaptor.model import Model, thaw
from td2adaptor.model.events import (
    ALL_ROBOTS,
    SCHEMA_BASE,
    TOPIC_ROOT,
    EventCatalog,
    EventSpec,
    Kind,
    build_catalog,
    td_topic,
)
from td2adaptor.model.wot import wot_data, wot_topic

TEMPLATES = Path(__file__).parent / "templates"


TD_CONTEXT = "https://www.w3.org/2022/wot/td/v1.1"
MQV_NAMESPACE = "http://www.example.org/mqtt-binding#"
ROBOT_PLACEHOLDER = "{{robotName}}"
BROKER_PLACEHOLDER = "{{mqttBroker}}"
#: the runtime publishes and subscribes with QoS 1 (the binding's `mqv:qos` is a string)
MQTT_QOS = "1"
#: the schema files declare JSON Schema 2020-12 (what the runtime validates with) and use only keywords that mean
#: the same in draft-07, the newest format AsyncAPI tools (@asyncapi/parser 3) register and so check
SCHEMA_FORMAT = "application/schema+json;version=draft-07"
MQTT_BINDING_VERSION = "0.2.0"


def dump(data: Any) -> str:
    """Deterministic JSON text: insertion order (TD order), two-space indent, final newline.

    orjson writes the layout of `json.dumps(indent=2, ensure_ascii=False)` (a test holds them equal; only a
    float's exponent may be spelled differently, both exact) ten times faster, which matters with one schema
    file per event; what orjson refuses (integers beyond 64 bits, very deep nesting) goes through `json`.
    """
    try:
        return orjson.dumps(data, option=orjson.OPT_INDENT_2 | orjson.OPT_APPEND_NEWLINE).decode("utf-8")
    except (orjson.JSONEncodeError, RecursionError):
        return json.dumps(data, indent=2, ensure_ascii=False) + "\n"


# ---------------------------------------------------------------------------------------------------------
# exposed TD


def td_schema(schema: Any) -> Any:
    """A JSON Schema reduced to TD data-schema terms (a TD has no `$ref`, `not`, `false` schemas, ...)."""
    if not isinstance(schema, Mapping):
        return {}
    out: dict[str, Any] = {}
    for key, value in schema.items():
        if key not in DATA_SCHEMA:
            continue
        if key == "properties" and isinstance(value, Mapping):
            out[key] = {n: td_schema(s) for n, s in value.items() if s is not False}
        elif key == "items" and isinstance(value, Mapping):
            out[key] = td_schema(value)
        elif key in ("oneOf", "allOf", "anyOf") and isinstance(value, list):
            out[key] = [td_schema(s) for s in value if isinstance(s, Mapping)]
        else:
            out[key] = value
    if "required" in out and "properties" in out:
        out["required"] = [r for r in out["required"] if r in out["properties"]]
    return out


def _texts(data: Mapping[str, Any]) -> dict[str, Any]:
    """`title` and (when not empty) `description` of `data`."""
    out: dict[str, Any] = {"title": data["title"]}
    if data.get("description"):
        out["description"] = data["description"]
    return out


def _wot_description(spec: EventSpec) -> str:
    if spec.kind is Kind.ERROR:
        return (
            "A request to an affordance (an action's input, a written value) was refused or failed: a stable "
            "code, a message in user words, the affordance and, when known, the correlationId and mission."
        )
    return f"{spec.description} Carries the correlationId sent with the action's input and the mission id."


def standalone(spec: EventSpec, catalog: EventCatalog) -> dict[str, Any]:
    """The event schema with the envelope merged in, as a self-contained TD data schema."""
    props: dict[str, Any] = {}
    for name, sub in catalog.envelope["properties"].items():
        own = spec.schema["properties"].get(name)
        if own is False:
            continue
        merged = dict(sub)
        if isinstance(own, Mapping) and "$ref" not in own:  # a reference is to `sub` itself
            merged.update({k: v for k, v in own.items() if k != "not"})
            if "const" in own:
                merged.pop("enum", None)
        props[name] = merged
    schema: dict[str, Any] = {
        "title": spec.title,
        "type": "object",
        "properties": props,
        "required": list(spec.schema["required"]),
    }
    if spec.description:
        schema["description"] = spec.description
    return dict(td_schema(schema))


def topic_href(broker: str, topic: str, *, model: bool = False) -> str:
    """`broker` with `topic` as its path, percent-encoded where a URI needs it (in a Thing Model the
    `{{...}}` placeholders stay as written, to be filled in textually): clients such as node-wot 0.8 take the
    topic from the href, others from `mqv:topic` / `mqv:filter`."""
    return f"{broker.rstrip('/')}/{quote(topic, safe='/{}' if model else '/')}"


def _form(
    broker: str,
    topic: str,
    op: str | list[str],
    packet: str,
    *,
    model: bool,
    retain: bool = False,
) -> dict[str, Any]:
    """A form of the W3C MQTT binding: the topic in the href path and in `mqv:topic` (publish) or `mqv:filter`
    (subscribe, unsubscribe); QoS 1 as the runtime uses; `mqv:retain` where the runtime retains."""
    form: dict[str, Any] = {"href": topic_href(broker, topic, model=model), "op": op, "contentType": "application/json"}
    form["mqv:controlPacket"] = packet
    form["mqv:topic" if packet == "publish" else "mqv:filter"] = topic
    if packet != "unsubscribe":
        form["mqv:qos"] = MQTT_QOS
    if retain:
        form["mqv:retain"] = True
    return form


def thing_id(model: Model, robot: str) -> str:
    """The exposed Thing's id: the TD's own with the robot id appended, else a URN of package and robot."""
    if model.thing.id:
        return f"{model.thing.id}:{robot}"
    return f"urn:td2adaptor:{model.package_name}:{robot}"


def exposed_td(
    model: Model,
    catalog: EventCatalog | None = None,
    *,
    robot: str | None = None,
    broker: str | None = None,
    root: str = TOPIC_ROOT,
) -> dict[str, Any]:
    """The Thing Description of robot `robot` on `broker` (`mqtt://host:port`): the robot's affordances with
    MQTT forms on the adaptor's topics. Without them, the Thing Model of the fleet: `{{robotName}}` and
    `{{mqttBroker}}` stand for the robot id and the broker URL."""
    catalog = catalog or build_catalog(model)
    is_model = robot is None or broker is None
    robot = ROBOT_PLACEHOLDER if robot is None else robot
    broker = BROKER_PLACEHOLDER if broker is None else broker
    thing = model.thing
    context: list[Any] = [TD_CONTEXT, {"mqv": MQV_NAMESPACE}]
    td: dict[str, Any] = {"@context": context, "@type": "tm:ThingModel" if is_model else "Thing"}
    td["id"] = thing_id(model, robot)
    td["title"] = thing.title
    description = f"{thing.title} ({robot}) through its td2adaptor event adaptor."
    if thing.description:
        description = f"{thing.description} {description}"
    td["description"] = description
    if thing.version:
        td["version"] = {"model" if is_model else "instance": thing.version}
    security = thaw(thing.security) if isinstance(thing.security, Mapping) and thing.security else None
    if not security:
        security = {"nosec_sc": {"scheme": "nosec"}}
    td["securityDefinitions"] = security
    td["security"] = list(security)
    properties: dict[str, Any] = {}
    actions: dict[str, Any] = {}
    events: dict[str, Any] = {}

    def form(topic: str, op: str | list[str], packet: str, retain: bool = False) -> dict[str, Any]:
        return _form(broker, topic, op, packet, model=is_model, retain=retain)

    runs = {s.run: s for s in catalog.specs if s.kind is Kind.QUERY and s.run}
    stops = {s.run: s for s in catalog.specs if s.kind is Kind.CANCEL and s.run}
    for spec in catalog.specs:
        topic = wot_topic(spec, robot, root)
        if topic is None:  # the status event: only its envelope topic, described as it travels
            data = standalone(spec, catalog)
            event = _texts(data)
            event["data"] = {k: v for k, v in data.items() if k not in ("title", "description")}
            event["forms"] = [
                form(spec.topic(robot, root), "subscribeevent", "subscribe", retain=True),
                form(spec.topic(robot, root), "unsubscribeevent", "unsubscribe"),
            ]
            events[spec.kind.value] = event
            continue
        data = dict(td_schema(wot_data(spec)))
        if spec.kind is Kind.PROPERTY and spec.affordance:
            prop = {**_texts({"title": spec.title, "description": spec.description}), **data}
            prop.update(readOnly=True, writeOnly=False, observable=True)
            prop["forms"] = [
                form(topic, ["readproperty", "observeproperty"], "subscribe", retain=True),
                form(topic, "unobserveproperty", "unsubscribe"),
            ]
            properties[spec.affordance] = prop
        elif spec.kind is Kind.WRITE and spec.affordance:
            prop = {**_texts({"title": spec.title, "description": spec.description}), **data}
            prop.update(readOnly=False, writeOnly=True, observable=False)
            prop["forms"] = [form(topic, "writeproperty", "publish")]
            properties[spec.affordance] = prop
        elif spec.kind in (Kind.INVOKE, Kind.QUERY, Kind.CANCEL) and spec.affordance:
            action = _texts({"title": spec.title, "description": spec.description})
            action["input"] = data
            action["safe"] = spec.kind is Kind.QUERY
            action["idempotent"] = spec.kind is not Kind.INVOKE
            action["synchronous"] = False
            action["forms"] = [form(topic, "invokeaction", "publish")]
            # TD 1.1's own operations on the run action, for clients that offer them: the same messages as
            # the query and cancel actions (answered by the run's state event)
            for op, linked in (
                ("queryaction", runs.get(spec.affordance)),
                ("cancelaction", stops.get(spec.affordance)),
            ):
                linked_topic = None if linked is None else wot_topic(linked, robot, root)
                if linked_topic is not None:
                    action["forms"].append(form(linked_topic, op, "publish"))
            actions[spec.affordance] = action
        else:
            name = {Kind.FEEDBACK: "Feedback", Kind.STATE: "State"}.get(spec.kind, "")
            key = f"{spec.affordance}{name}" if spec.affordance else spec.kind.value
            event = _texts({"title": spec.title, "description": _wot_description(spec)})
            event["data"] = data
            event["forms"] = [
                form(topic, "subscribeevent", "subscribe"),
                form(topic, "unsubscribeevent", "unsubscribe"),
            ]
            events[key] = event
    for name, section in (("properties", properties), ("actions", actions), ("events", events)):
        if section:
            td[name] = section
    return td


# ---------------------------------------------------------------------------------------------------------
# AsyncAPI 3.0


def _security_schemes(model: Model) -> dict[str, Any]:
    schemes: dict[str, Any] = {}
    security = model.thing.security if isinstance(model.thing.security, Mapping) else {}
    for name, definition in security.items():
        scheme = definition.get("scheme") if isinstance(definition, Mapping) else None
        if scheme == "basic":
            schemes[name] = {"type": "userPassword", "description": "MQTT username and password."}
        elif scheme == "psk":
            schemes[name] = {"type": "symmetricEncryption", "description": "TLS pre-shared key."}
    return schemes


def asyncapi(model: Model, catalog: EventCatalog | None = None, *, root: str = TOPIC_ROOT) -> dict[str, Any]:
    """An AsyncAPI 3.0 document of the adaptor (the application described is the adaptor)."""
    catalog = catalog or build_catalog(model)
    channels: dict[str, Any] = {}
    operations: dict[str, Any] = {}
    messages: dict[str, Any] = {}
    replies = {
        Kind.INVOKE: Kind.FEEDBACK,
        Kind.QUERY: Kind.STATE,
        Kind.CANCEL: Kind.STATE,
    }
    for spec in catalog.specs:
        msg_ref = {"$ref": f"#/components/messages/{spec.key}"}
        message: dict[str, Any] = {
            "name": spec.key,
            "title": spec.title,
            "contentType": "application/json",
            "correlationId": {"location": "$message.payload#/correlation"},
            "payload": {"schemaFormat": SCHEMA_FORMAT, "schema": {"$ref": spec.schema_ref}},
        }
        if spec.description:
            message["summary"] = spec.description
        messages[spec.key] = message
        robots = [("{robot}", spec.key)]
        if spec.kind.inbound:
            robots.append((ALL_ROBOTS, f"{spec.key}.{ALL_ROBOTS}"))
        for robot, channel_key in robots:
            channel: dict[str, Any] = {"address": spec.topic(robot, root), "title": spec.title}
            if robot == ALL_ROBOTS:
                channel["description"] = "The all-robots channel: every adaptor of this Thing receives it."
            else:
                channel["parameters"] = {"robot": {"$ref": "#/components/parameters/robot"}}
            channel["messages"] = {spec.key: msg_ref}
            channels[channel_key] = channel
            retain = spec.kind in (Kind.PROPERTY, Kind.STATUS)
            operation: dict[str, Any] = {
                "action": "receive" if spec.kind.inbound else "send",
                "channel": {"$ref": f"#/channels/{channel_key}"},
                "title": spec.title,
                "messages": [{"$ref": f"#/channels/{channel_key}/messages/{spec.key}"}],
                "bindings": {"mqtt": {"qos": 1, "retain": retain, "bindingVersion": MQTT_BINDING_VERSION}},
            }
            reply_kind = replies.get(spec.kind)
            if reply_kind is not None:
                target = spec.run if spec.kind is not Kind.INVOKE else spec.affordance
                reply = catalog.find(reply_kind, target)
                operation["reply"] = {
                    "channel": {"$ref": f"#/channels/{reply.key}"},
                    "messages": [{"$ref": f"#/channels/{reply.key}/messages/{reply.key}"}],
                }
            prefix = "receive" if spec.kind.inbound else "send"
            operations[f"{prefix}.{channel_key}"] = operation
    schemes = _security_schemes(model)
    server: dict[str, Any] = {
        "host": "{host}",
        "protocol": "mqtt",
        "protocolVersion": "5",
        "description": (
            "The MQTT broker the adaptors and applications share. Adaptors connect with a persistent session "
            f"(client id td2adaptor-<robot>) and QoS 1, and leave {root}/<robot>/status offline as their last will."
        ),
        "variables": {"host": {"default": "localhost:1883", "description": "Broker host and port."}},
        "bindings": {
            "mqtt": {
                "cleanSession": False,
                "keepAlive": 30,
                "sessionExpiryInterval": 3600,
                "bindingVersion": MQTT_BINDING_VERSION,
            }
        },
    }
    if schemes:
        server["security"] = [{"$ref": f"#/components/securitySchemes/{n}"} for n in schemes]
    thing = model.thing
    info: dict[str, Any] = {"title": f"{thing.title} events", "version": thing.version or "1.0.0"}
    info["description"] = (
        f"Events of the td2adaptor adaptor of {thing.title}: applications publish invoke, query, cancel and "
        "write events; the adaptor answers with feedback on every state change, state, property, error and "
        "status events."
    )
    components: dict[str, Any] = {
        "messages": messages,
        "parameters": {
            "robot": {
                "description": f"Robot id (the reserved id {ALL_ROBOTS!r} is the all-robots channel).",
                "examples": ["rb1_base_a"],
            }
        },
    }
    if schemes:
        components["securitySchemes"] = schemes
    return {
        "asyncapi": "3.0.0",
        "info": info,
        "defaultContentType": "application/json",
        "servers": {"broker": server},
        "channels": channels,
        "operations": operations,
        "components": components,
    }


# ---------------------------------------------------------------------------------------------------------
# README


def _readme(model: Model, catalog: EventCatalog) -> str:
    env = environment(TEMPLATES, trim=False)
    rows = [
        {
            "topic": spec.topic("<robot>"),
            "direction": "in" if spec.kind.inbound else "out",
            "kind": spec.kind.value,
            "schema": spec.schema_ref,
            "file": spec.schema_file,
        }
        for spec in catalog.specs
    ]
    return env.get_template("README.md.j2").render(
        title=ts.md_inline(model.thing.title), package=catalog.package, rows=rows, all_robots=ALL_ROBOTS
    )


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    """Schemas, AsyncAPI document, exposed TD, README and broker ACL of `model`'s events, under `<package>/`."""
    del options  # nothing to choose, nothing that can fail: every model has an event contract
    for comp in model.components:
        for a in comp.actions:
            diags.warning(
                "GEN860",
                f"events backend: {comp.name}.{a.name}: ROS action {a.ros_name.binding_form()} ({a.type_name}) is "
                "not in the event contract yet: skipped",
                a.pointer,
            )
    catalog = build_catalog(model)
    folder = f"{catalog.package}/"
    tree = GeneratedTree()
    tree.add(folder + "README.md", _readme(model, catalog))
    tree.add(folder + "asyncapi.json", dump(asyncapi(model, catalog)))
    tree.add(folder + "td.mqtt.json", dump(exposed_td(model, catalog)))
    for path, document in catalog.files:
        tree.add(folder + path, dump(document))
    tree.add(folder + "mosquitto.acl", _acl(model, catalog))
    return tree


def _acl(model: Model, catalog: EventCatalog) -> str:
    """mosquitto's ACL for these events: each edge node (user = robot id) publishes only its robot's outbound
    topics and reads its inbound ones; an `application` user publishes the inbound ones; nobody else."""
    inbound = [s for s in catalog.specs if s.kind.inbound]
    outbound = [s for s in catalog.specs if not s.kind.inbound]
    env = environment(TEMPLATES, trim=True)
    return env.get_template("mosquitto.acl.j2").render(
        title=ts.py_comment(model.thing.title),
        package=catalog.package,
        root=TOPIC_ROOT,
        all_robots=ALL_ROBOTS,
        node_reads=[t for s in inbound for t in (s.topic("%u"), s.topic(ALL_ROBOTS), wot_topic(s, "%u")) if t],
        node_writes=[
            *(s.topic("%u") for s in outbound),
            *(t for s in outbound if (t := wot_topic(s, "%u"))),
            td_topic("%u"),
        ],
        app_writes=[t for s in inbound for t in (s.topic("+"), wot_topic(s, "+")) if t],
    )


INDEX = "README.md"


def finish(tree: GeneratedTree) -> GeneratedTree:
    """OUT/events/ with every TD's folder merged in: add the index of the packages (sorted by name, so the
    order of the TDs does not matter) and what their adaptors share."""
    packages = []
    for path in sorted(tree.files):
        package, _, rest = path.partition("/")
        if rest != "td.mqtt.json":
            continue
        title = json.loads(tree.files[path]).get("title")
        packages.append({"name": package, "title": ts.md_inline(title if isinstance(title, str) else package)})
    env = environment(TEMPLATES, trim=False)
    text = env.get_template("index.md.j2").render(
        packages=packages, root=TOPIC_ROOT, all_robots=ALL_ROBOTS, schema_base=SCHEMA_BASE
    )
    out = GeneratedTree(dict(tree.files), set(tree.executable))
    out.add(INDEX, text)
    return out
