"""The Thing Description a robot exposes on the bus (and the fleet's Thing Model): its affordances with W3C MQTT
binding forms on the adaptor's topics.

It lives with the model, not in the events backend, because the edge node publishes it at run time
(`td2adaptor run`, `td2adaptor expose`) as well as the backend writing the fleet's Thing Model.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any
from urllib.parse import quote

from td2adaptor.model import Model, thaw
from td2adaptor.model.events import TOPIC_ROOT, EventCatalog, EventSpec, Kind, build_catalog
from td2adaptor.model.vocabulary import DATA_SCHEMA
from td2adaptor.model.wot import wot_data, wot_topic

TD_CONTEXT = "https://www.w3.org/2022/wot/td/v1.1"
MQV_NAMESPACE = "http://www.example.org/mqtt-binding#"
#: the media type of a Thing Model (TD 1.1), on a robot TD's `rel: type` link to the model it instantiates
TM_MEDIA_TYPE = "application/tm+json"
ROBOT_PLACEHOLDER = "{{robotName}}"
BROKER_PLACEHOLDER = "{{mqttBroker}}"
#: the QoS a consumer publishes and subscribes with (the binding's `mqv:qos` is a string): 1, as the runtime
#: publishes. (The node subscribes the WoT command topics at QoS 0, so that the broker does not queue commands
#: for it while it is away; that is its own subscription, not what the consumer's forms say.)
MQTT_QOS = "1"


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


def texts(data: Mapping[str, Any]) -> dict[str, Any]:
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
    return spec.description  # what every feedback and state event carries: said once, in the Thing's description


#: said once in the Thing's description rather than in each feedback and state event's (their `correlationId`
#: and `mission` members say it too): the published TD must stay small (docs/fleet.md, the directory limit)
OUTCOME_TEXT = (
    "Every feedback and state event carries the correlationId sent with the action's input and the mission id."
)


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


#: the W3C MQTT binding's default control packet of each operation (its "Default mappings"): a form whose
#: operations all have their default says none, and each operation takes its own (a subscription form with
#: `subscribeevent` and `unsubscribeevent` sends SUBSCRIBE for the one, UNSUBSCRIBE for the other)
DEFAULT_PACKET = {
    "readproperty": "subscribe",
    "observeproperty": "subscribe",
    "unobserveproperty": "unsubscribe",
    "writeproperty": "publish",
    "invokeaction": "publish",
    "subscribeevent": "subscribe",
    "unsubscribeevent": "unsubscribe",
}


def _form(
    broker: str,
    topic: str,
    op: str | list[str],
    *,
    model: bool,
    retain: bool = False,
    qos: str = MQTT_QOS,
) -> dict[str, Any]:
    """A form of the W3C MQTT binding: the topic in the href path and in `mqv:topic` (publish) or `mqv:filter`
    (subscribe and unsubscribe: one form for both); the QoS the runtime uses; `mqv:retain` where the runtime
    retains. What TD 1.1 or the binding implies is left out, as the published TD must stay small (a directory
    such as Domus 1.0.2 cannot give back a TD whose RDF passes 128 KiB, docs/fleet.md): `contentType`
    (`application/json`, TD 1.1's default) and `mqv:controlPacket` where the binding's default mapping gives it
    (stated for `queryaction` and `cancelaction` only, which the binding maps to nothing)."""
    ops = [op] if isinstance(op, str) else op
    packets = {DEFAULT_PACKET.get(o) for o in ops}
    form: dict[str, Any] = {"href": topic_href(broker, topic, model=model), "op": op}
    if None in packets:  # an operation without a default: what the runtime takes it as, a publish
        form["mqv:controlPacket"] = "publish"
    form["mqv:topic" if packets <= {"publish", None} else "mqv:filter"] = topic
    form["mqv:qos"] = qos
    if retain:
        form["mqv:retain"] = True
    return form


#: the security an exposed TD declares when the edge node logs in to the broker and its TD declares none
BROKER_LOGIN = {
    "scheme": "basic",
    "description": "The MQTT broker's user name and password: the broker refuses clients without them.",
}


def _only_nosec(security: Mapping[str, Any]) -> bool:
    """Whether every security definition of a TD is `nosec`: it asks nothing of a consumer."""
    return all(isinstance(d, Mapping) and d.get("scheme") == "nosec" for d in security.values())


#: the property that tells whether the robot is there: its edge node's status (named otherwise when the robot
#: has a property of that name)
PRESENCE_PROPERTY = "presence"


def _free(name: str, taken: Mapping[str, Any]) -> str:
    """`name`, or `td2adaptor` + Name when `taken` has it already."""
    return name if name not in taken else f"td2adaptor{name[:1].upper()}{name[1:]}"


def _presence(data: Mapping[str, Any], forms: list[dict[str, Any]]) -> dict[str, Any]:
    """The robot's presence as a property a WoT consumer reads and observes: the retained status event itself
    (the TD's `status` event: `data` is its schema, of which the property names only the payload, the rest being
    the envelope the event describes already), which the broker's will turns `offline` when the edge node dies
    (MQTT gives a connection one will, so the property is that topic rather than one of its own)."""
    payload = data["properties"]["payload"]
    return {
        "title": "Presence",
        "description": "Whether the robot can be used now: the retained status event, whose payload says state "
        "online (its edge node serves it) or offline (the node stopped or died); while online, robot present, "
        "partial or absent (its ROS side: the servers of its actions; an action invoked while its server is not "
        "there is answered at once with an absent error), the owner process, the missions in flight and the last "
        "error.",
        "type": "object",
        "properties": {"payload": payload},
        "required": ["payload"],
        "readOnly": True,
        "observable": True,
        "forms": forms,
    }


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
    property_qos: int = 1,
    authenticated: bool = False,
) -> dict[str, Any]:
    """The Thing Description of robot `robot` on `broker` (`mqtt://host:port`): the robot's affordances with
    MQTT forms on the adaptor's topics. Without them, the Thing Model of the fleet: `{{robotName}}` and
    `{{mqttBroker}}` stand for the robot id and the broker URL. `property_qos`: the QoS property events are
    published with (the run configuration's), which the observe forms say: a consumer receives them at it.
    `authenticated`: the edge node logs in to the broker with a user name and password, so the broker wants
    them: a TD that declares no security (nosec) is exposed with `basic` security, which is what makes a WoT
    consumer present its credentials (node-wot sends none for nosec, and a password-only broker refuses it)."""
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
    # a Thing Model's own description tells how to use the model ("instantiate it per robot ..."): the fleet's
    # model keeps it, a robot's TD says which robot it is and links the model instead
    if thing.description and (is_model or not thing.model_description):
        description = f"{thing.description} {description}"
    if any(s.kind in (Kind.FEEDBACK, Kind.STATE) for s in catalog.specs):
        description = f"{description} {OUTCOME_TEXT}"
    td["description"] = description
    if thing.model and not is_model:
        td["links"] = [{"rel": "type", "href": thing.model, "type": TM_MEDIA_TYPE}]
    if thing.version:
        td["version"] = {"model" if is_model else "instance": thing.version}
    security = thaw(thing.security) if isinstance(thing.security, Mapping) and thing.security else None
    if not security:
        security = {"nosec_sc": {"scheme": "nosec"}}
    if authenticated and _only_nosec(security):
        security = {"basic_sc": dict(BROKER_LOGIN)}
    td["securityDefinitions"] = security
    td["security"] = list(security)
    properties: dict[str, Any] = {}
    actions: dict[str, Any] = {}
    events: dict[str, Any] = {}

    def form(topic: str, op: str | list[str], *, retain: bool = False, qos: str = MQTT_QOS) -> dict[str, Any]:
        return _form(broker, topic, op, model=is_model, retain=retain, qos=qos)

    runs = {s.run: s for s in catalog.specs if s.kind is Kind.QUERY and s.run}
    stops = {s.run: s for s in catalog.specs if s.kind is Kind.CANCEL and s.run}
    for spec in catalog.specs:
        topic = wot_topic(spec, robot, root)
        if topic is None:  # the status event: only its envelope topic, described as it travels
            data = standalone(spec, catalog)
            event = texts(data)
            event["data"] = {k: v for k, v in data.items() if k not in ("title", "description")}
            event["forms"] = [form(spec.topic(robot, root), ["subscribeevent", "unsubscribeevent"], retain=True)]
            events[spec.kind.value] = event
            ops = ["readproperty", "observeproperty", "unobserveproperty"]
            status_forms = [form(spec.topic(robot, root), ops, retain=True)]
            properties[_free(PRESENCE_PROPERTY, properties)] = _presence(event["data"], status_forms)
            continue
        data = dict(td_schema(wot_data(spec)))
        if spec.kind is Kind.PROPERTY and spec.affordance:
            prop = {**texts({"title": spec.title, "description": spec.description}), **data}
            prop.update(readOnly=True, observable=True)  # writeOnly: false is TD 1.1's default
            ops = ["readproperty", "observeproperty", "unobserveproperty"]
            prop["forms"] = [form(topic, ops, retain=True, qos=str(property_qos))]
            properties[spec.affordance] = prop
        elif spec.kind is Kind.WRITE and spec.affordance:
            prop = {**texts({"title": spec.title, "description": spec.description}), **data}
            prop["writeOnly"] = True  # readOnly and observable: false, TD 1.1's default
            prop["forms"] = [form(topic, "writeproperty")]
            properties[spec.affordance] = prop
        elif spec.kind in (Kind.INVOKE, Kind.QUERY, Kind.CANCEL) and spec.affordance:
            action = texts({"title": spec.title, "description": spec.description})
            action["input"] = data
            if spec.kind is Kind.QUERY:  # safe and idempotent: false is TD 1.1's default
                action["safe"] = True
            if spec.kind is not Kind.INVOKE:
                action["idempotent"] = True
            action["synchronous"] = False
            action["forms"] = [form(topic, "invokeaction")]
            # TD 1.1's own operations on the run action, for clients that offer them: the same messages as
            # the query and cancel actions (answered by the run's state event)
            for op, linked in (
                ("queryaction", runs.get(spec.affordance) if spec.kind is Kind.INVOKE else None),
                ("cancelaction", stops.get(spec.affordance) if spec.kind is Kind.INVOKE else None),
            ):
                linked_topic = None if linked is None else wot_topic(linked, robot, root)
                if linked_topic is not None:
                    action["forms"].append(form(linked_topic, op))
            # a ROS action's query and cancel have no TD affordance of their own: name them after it
            suffix = spec.kind.value.capitalize() if spec.goal_control else ""
            actions[spec.affordance + suffix] = action
        else:
            name = {Kind.FEEDBACK: "Feedback", Kind.STATE: "State"}.get(spec.kind, "")
            key = f"{spec.affordance}{name}" if spec.affordance else spec.kind.value
            event = texts({"title": spec.title, "description": _wot_description(spec)})
            event["data"] = data
            event["forms"] = [form(topic, ["subscribeevent", "unsubscribeevent"])]
            events[key] = event
    for name, section in (("properties", properties), ("actions", actions), ("events", events)):
        if section:
            td[name] = section
    return td
