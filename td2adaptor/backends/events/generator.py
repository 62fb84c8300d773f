"""`--backend events`: the event contract of an adaptor, for applications that talk to robots over a bus.

Writes, under OUT/events/<package>/ (one folder per adaptor package, so the robots of one system generate
into one output side by side):

* `schemas/<Component>.events.schema.json`: JSON Schema 2020-12 of every event of a component, each under
  `$defs/<affordance>.<kind>` (see `td2adaptor.model.events` for the topic scheme); `schemas/error.schema.json` and
  `schemas/status.schema.json` for the robot-level events; all refer to `schemas/envelope.schema.json` for
  the shared fields. Every `$id` is `https://td2adaptor.dev/events/<package>/schemas/<file>`: the layout of
  OUT/events/ mirrors the ids, so relative references resolve between the files and no two packages share one;
* `asyncapi.json`: an AsyncAPI 3.1 document (MQTT channels, operations, messages referring to the schemas);
* `td.mqtt.json`: the Thing Model of the robots' exposed Thing Descriptions: the same Thing with W3C MQTT
  binding forms (`mqv:`, the topic also in the href path), so a standard WoT consumer can invoke the actions,
  observe the properties and subscribe to the feedback; `{{robotName}}` stands for the robot id and
  `{{mqttBroker}}` for the broker URL. `td2adaptor expose` writes the TD of one robot and `td2adaptor run`
  publishes it, retained, on `td2adaptor/<robot>/td`;
* `README.md`: the topic table;
* `mosquitto.acl`: the broker's access control, one `user` block per robot (`events.robots`, see `_acl`).

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

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation import textsafe as ts
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.generation.templating import environment
from td2adaptor.model import Model
from td2adaptor.model.events import (
    ALL_ROBOTS,
    ROBOT_ID,
    SCHEMA_BASE,
    TOPIC_ROOT,
    EventCatalog,
    Kind,
    build_catalog,
    command_filters,
    td_topic,
)
from td2adaptor.model.exposed import (  # noqa: F401 - the exposed TD's pieces, named here as before
    BROKER_PLACEHOLDER,
    MQTT_QOS,
    MQV_NAMESPACE,
    ROBOT_PLACEHOLDER,
    TD_CONTEXT,
    exposed_td,
    standalone,
    td_schema,
    texts,
    thing_id,
    topic_href,
)
from td2adaptor.model.wot import wot_command_filters, wot_topic
from td2adaptor.support.jsondump import dump

TEMPLATES = Path(__file__).parent / "templates"


#: the schema files declare JSON Schema 2020-12 (what the runtime validates with) and use only keywords that mean
#: the same in draft-07, the newest format AsyncAPI tools (@asyncapi/parser 3) register and so check
SCHEMA_FORMAT = "application/schema+json;version=draft-07"
MQTT_BINDING_VERSION = "0.2.0"


# ---------------------------------------------------------------------------------------------------------
# AsyncAPI 3.1


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
    """An AsyncAPI 3.1 document of the adaptor (the application described is the adaptor)."""
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
        "asyncapi": "3.1.0",
        "info": info,
        "defaultContentType": "application/json",
        "servers": {"broker": server},
        "channels": channels,
        "operations": operations,
        "components": components,
    }


# ---------------------------------------------------------------------------------------------------------
# schema files


def portable(schema: Any) -> Any:
    """A schema document as code generators read it: a member an event must not carry is left out of its
    closed object instead of given the boolean schema `false`.

    In memory the contract marks such members `false` (so the runtime can name one in its refusal); with
    `additionalProperties: false` beside them, leaving them out means the same, and AsyncAPI Modelina
    (`asyncapi generate models`) refuses boolean subschemas where `{"not": {}}` would give every model a field
    that must stay empty."""
    if isinstance(schema, (str, bool, int, float)) or schema is None:  # most values: no ABC check (half the time)
        return schema
    if isinstance(schema, list):
        return [portable(s) for s in schema]
    if not isinstance(schema, Mapping):
        return schema
    out: dict[str, Any] = {}
    for key, value in schema.items():
        if key == "properties" and isinstance(value, Mapping) and schema.get("additionalProperties") is False:
            out[key] = {name: portable(sub) for name, sub in value.items() if sub is not False}
        elif key in ("properties", "$defs") and isinstance(value, Mapping):
            out[key] = {name: portable(sub) for name, sub in value.items()}
        else:
            out[key] = portable(value)
    return out


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


#: the option that names the robots the broker ACL is written for
ROBOTS_OPTION = "events.robots"
#: who the ACL's node block is for when no robot ids are given: no robot id can be it, no robot gets its rights
ROBOT_STANDIN = "<robot>"
#: the user of an edge process that serves robots not known in advance (`run --discover`, admin requests): the
#: ACL lets it act as any robot of this Thing
FLEET_NODE = "fleet-node"
#: the users the ACL has blocks for besides the robots' (mosquitto.acl.j2): no robot may be named so
ACL_USERS = (FLEET_NODE, "fleet-admin", "application")


#: the option that names the fleet whose admin requests the ACL lets through (default: the package name)
FLEET_OPTION = "events.fleet"
#: the level under the topic root where admin requests of a fleet go (runtime/node/admin.py: no robot id is it)
ADMIN_LEVEL = ".fleet"


def _fleet(options: GenOptions, diags: Diagnostics) -> str | None:
    """The fleet name of `events.fleet`, checked as a robot id is (one topic level, no wildcard)."""
    fleet = None
    for key, raw in options.extra:
        if key != FLEET_OPTION:
            continue
        if not isinstance(raw, str) or not ROBOT_ID.match(raw) or raw == ALL_ROBOTS:
            diags.error(
                "GEN860",
                f"events backend: {FLEET_OPTION}: {raw!r} is not a fleet name (1-128 letters, digits, '_', '.', "
                "'-'); in the broker ACL a '/', '+' or '#' in it would open other topics",
            )
        else:
            fleet = raw
    return fleet


def _robots(options: GenOptions, diags: Diagnostics) -> list[str]:
    """The robot ids of `events.robots` (a list, or one string of ids separated by commas), each checked: an id
    with '/', '+' or '#' would name other robots' topics in the ACL (`_acl`), so none is accepted that a robot's
    configuration would refuse."""
    robots: list[str] = []
    for key, raw in options.extra:
        if not key.startswith("events.") or key == FLEET_OPTION:
            continue
        if key != ROBOTS_OPTION:
            known = f"{ROBOTS_OPTION}, {FLEET_OPTION}"
            diags.error("GEN860", f"events backend: unknown option {key!r}", hint=f"known: {known}")
            continue
        items = raw.split(",") if isinstance(raw, str) else raw if isinstance(raw, list) else None
        if items is None or not items:
            diags.error("GEN860", f"events backend: {ROBOTS_OPTION} must be a list of robot ids")
            continue
        for item in items:
            robot = item.strip() if isinstance(item, str) else item
            if not isinstance(robot, str) or not ROBOT_ID.match(robot) or robot == ALL_ROBOTS:
                diags.error(
                    "GEN860",
                    f"events backend: {ROBOTS_OPTION}: {robot!r} is not a robot id (1-128 letters, digits, '_', "
                    f"'.', '-', not {ALL_ROBOTS!r}); in the broker ACL a '/', '+' or '#' in it would open other "
                    "robots' topics",
                )
            elif robot in robots:
                diags.error("GEN860", f"events backend: {ROBOTS_OPTION} names {robot!r} twice")
            elif robot in ACL_USERS:
                diags.error(
                    "GEN860",
                    f"events backend: {ROBOTS_OPTION}: {robot!r} is a user the broker ACL has a block of its own for "
                    "(its block would add to the robot's rights): name the robot otherwise",
                )
            else:
                robots.append(robot)
    return robots


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    """Schemas, AsyncAPI document, exposed TD, README and broker ACL of `model`'s events, under `<package>/`."""
    robots = _robots(options, diags)
    fleet = _fleet(options, diags)
    catalog = build_catalog(model)
    folder = f"{catalog.package}/"
    tree = GeneratedTree()
    tree.add(folder + "README.md", _readme(model, catalog))
    tree.add(folder + "asyncapi.json", dump(asyncapi(model, catalog)))
    tree.add(folder + "td.mqtt.json", dump(exposed_td(model, catalog)))
    for path, document in catalog.files:
        tree.add(folder + path, dump(portable(document)))
    tree.add(folder + "mosquitto.acl", _acl(model, catalog, robots, fleet or catalog.package))
    return tree


def _acl(model: Model, catalog: EventCatalog, robots: list[str], fleet: str) -> str:
    """mosquitto's ACL for these events: each edge node (user = robot id) publishes only its robot's outbound
    topics and reads its inbound ones; an `application` user publishes the inbound ones; nobody else.

    Each robot gets a `user` block with its topics written out, not `pattern` lines with `%u`: mosquitto 2.0
    puts the user name into `%u` as it is, '/' included, so a user `<robot>/wot-thing` would be granted, by the
    node's envelope patterns, that robot's WoT topics (forge its feedback, errors and property values, read its
    commands), and no pattern can tell the two apart. Without robot ids (`events.robots`), one block for the
    stand-in `<robot>` shows what each robot needs. The fleet's admin requests (`td2adaptor run`, docs/fleet.md):
    every edge node reads them and writes their answers; the `fleet-admin` user writes them and reads the answers.
    `fleet-node`: the node block with `+` for the robot, for a process that serves robots it discovers or is asked
    to add (their ids are not known when the ACL is written; it may act as any robot of this Thing).
    `run --share`: every edge node may keep a member record, beat, record admitted invokes and read every robot's
    status (node/share.py), since a process's member connection has its top-level user, a robot's."""
    inbound = [s for s in catalog.specs if s.kind.inbound]
    outbound = [s for s in catalog.specs if not s.kind.inbound]

    def node(robot: str) -> dict[str, Any]:
        # the filters the node subscribes (runtime/engine.py): its commands, also on topics no event is defined
        # on (answered unknown-topic), and the all-robots channel's own command topics
        reads = [
            *command_filters(catalog, robot),
            *wot_command_filters(robot),
            *(s.topic(ALL_ROBOTS) for s in inbound),
            # its own retained status, read before it serves the robot: is another process serving it? (owner)
            catalog.find(Kind.STATUS).topic(robot),
        ]
        writes = [
            *(s.topic(robot) for s in outbound),
            *(t for s in outbound if (t := wot_topic(s, robot))),
            td_topic(robot),
        ]
        return {
            "id": robot,
            # (once each: with `+` for the robot, its own status is every robot's, which a member reads)
            "reads": list(dict.fromkeys([*reads, admin_request, *share_reads])),
            "writes": list(dict.fromkeys([*writes, admin_answer, *share_writes])),
        }

    admin_request = f"{TOPIC_ROOT}/{ADMIN_LEVEL}/{fleet}/request"
    admin_answer = f"{TOPIC_ROOT}/{ADMIN_LEVEL}/{fleet}/answer"
    # `run --share` (runtime/node/share.py): the member connection, under the user of the fleet file's top-level
    # settings (a robot's), keeps its record and will on members/<node>, beats on beats/<node>, records each
    # admitted invoke on admitted/<robot>/<key> for whichever robot the process serves, and reads every robot's
    # status (is it free?); the robots admin requests added are retained on robots/<robot>, which the member that
    # answers a request writes and every member reads. Node names and the robots a process serves change at run
    # time: `+`, not names.
    share = f"{TOPIC_ROOT}/{ADMIN_LEVEL}/{fleet}"
    share_writes = [f"{share}/members/+", f"{share}/beats/+", f"{share}/admitted/+/+", f"{share}/robots/+"]
    share_reads = [
        f"{share}/members/#",
        f"{share}/beats/+",
        f"{share}/admitted/+/+",
        f"{share}/robots/+",
        f"{TOPIC_ROOT}/+/status",
    ]

    env = environment(TEMPLATES, trim=True)
    return env.get_template("mosquitto.acl.j2").render(
        title=ts.py_comment(model.thing.title),
        package=catalog.package,
        root=TOPIC_ROOT,
        all_robots=ALL_ROBOTS,
        option=ROBOTS_OPTION,
        nodes=[node(robot) for robot in robots or [ROBOT_STANDIN]],
        given=bool(robots),
        fleet_node={**node("+"), "id": FLEET_NODE},
        app_writes=[t for s in inbound for t in (s.topic("+"), wot_topic(s, "+")) if t],
        fleet=fleet,
        admin_request=admin_request,
        admin_answer=admin_answer,
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
