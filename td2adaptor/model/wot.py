"""The robot as a plain WoT Thing: the topics and data a WoT consumer sees, derived from the event contract.

The events of `model.events` wrap every payload in the project's envelope (type, robot, id, time, source,
correlation, mission). A WoT consumer knows nothing of it: the Scripting API's `invokeAction(name, input)`
sends the action's input as the whole message, `readProperty` expects the property's own value. So the robot
also offers its affordances without the envelope, on topics of their own (the exposed TD's forms point
there); the edge node's bus adapter (`runtime/bus/thingbus.py`) translates between the two:

    <root>/<robot>/wot-thing/<Component>/<affordance>           property value (out, retained) or written
                                                                value (in); action input (in)
    <root>/<robot>/wot-thing/<Component>/<action>/feedback      every state change of an invocation (out)
    <root>/<robot>/wot-thing/<Component>/<run>/state            answer to a query or cancel (out)
    <root>/<robot>/wot-thing/error                              an invocation or write refused or failed (out)

`wot-thing` cannot be a component name (components are identifiers, without `-`), so these topics never meet
the envelope topics of `model.events`.

Correlation: the Scripting API gives a consumer no handle on an MQTT invocation (nothing comes back on the
publish), so every action input may carry an optional `correlationId` (declared in the TD); the adapter makes
it the envelope's correlation and every feedback, state or error event answering that invocation carries it
back, with the robot's `mission` id. An action whose goal has a field of that name gets none (the goal wins);
its consumers follow the one mission a component runs at a time by its `mission` id.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from td2adaptor.model.events import GOAL_ID, TOPIC_ROOT, EventCatalog, EventSpec, Kind

WOT_LEVEL = "wot-thing"
CORRELATION = "correlationId"
_CORRELATION_SCHEMA = {
    "description": "Optional, chosen by the consumer: every event answering this invocation carries it back.",
    "type": "string",
    "minLength": 1,
    "maxLength": 256,
}
_MISSION_SCHEMA = {
    "description": "The mission id the robot assigned to the run.",
    "type": "integer",
    "minimum": -(2**63),
    "maximum": 2**64 - 1,
}


def wot_topic(spec: EventSpec, robot: str, root: str = TOPIC_ROOT) -> str | None:
    """The WoT consumer's topic of `spec` (None for the status event, which has only its envelope topic).

    Invoke, query and cancel share their action's topic; write and property their property's."""
    if spec.kind is Kind.STATUS:
        return None
    base = f"{root}/{robot}/{WOT_LEVEL}"
    if spec.kind is Kind.ERROR:
        return f"{base}/error"
    topic = f"{base}/{spec.component}/{spec.affordance}"
    if spec.kind in (Kind.FEEDBACK, Kind.STATE) or spec.goal_control:  # a ROS action's query/cancel: own topics
        return f"{topic}/{spec.kind.value}"
    return topic


def wot_command_filters(robot: str, root: str = TOPIC_ROOT) -> list[str]:
    """The MQTT filters on which `robot`'s edge node takes WoT commands, also for affordances the Thing does not
    have (answered `unknown-topic`): `<Component>/<affordance>` (action inputs, written values; also where the
    node publishes property values, which it drops on arrival) and a ROS action goal's `.../query` and
    `.../cancel`. None of them matches an envelope topic (the component level is `wot-thing`) or the node's
    feedback, state and error topics."""
    base = f"{root}/{robot}/{WOT_LEVEL}"
    return [f"{base}/+/+", f"{base}/+/+/{Kind.QUERY.value}", f"{base}/+/+/{Kind.CANCEL.value}"]


def takes_correlation(spec: EventSpec) -> bool:
    """Whether the action input of invoke event `spec` has room for `correlationId` (an object whose goal has
    no field of that name)."""
    payload = spec.schema["properties"].get("payload")
    if spec.kind in (Kind.QUERY, Kind.CANCEL):
        return True
    if not isinstance(payload, Mapping) or payload.get("type") != "object":
        return False
    return CORRELATION not in (payload.get("properties") or {})


def action_input(spec: EventSpec) -> dict[str, Any]:
    """The data a WoT consumer sends to invoke, query or cancel: the goal's own fields (query and cancel:
    which mission), plus the optional `correlationId`."""
    if spec.goal_control:  # a ROS action's goal: named by its goal id
        return {
            "type": "object",
            "properties": {
                "goal": {**GOAL_ID, "description": "Which goal; default the current or last one."},
                CORRELATION: dict(_CORRELATION_SCHEMA),
            },
            "additionalProperties": False,
        }
    if spec.kind in (Kind.QUERY, Kind.CANCEL):
        return {
            "type": "object",
            "properties": {
                "mission": {**_MISSION_SCHEMA, "description": "Which mission; default the current or last one."},
                CORRELATION: dict(_CORRELATION_SCHEMA),
            },
            "additionalProperties": False,
        }
    payload = spec.schema["properties"].get("payload")
    schema = dict(payload) if isinstance(payload, Mapping) else {"type": "object"}
    if takes_correlation(spec):
        fields = schema.get("properties")
        schema["properties"] = {
            **(fields if isinstance(fields, Mapping) else {}),
            CORRELATION: dict(_CORRELATION_SCHEMA),
        }
    return schema


def property_value(spec: EventSpec) -> dict[str, Any]:
    """A property's own data (read, observed or written): the event's payload schema."""
    payload = spec.schema["properties"].get("payload")
    return dict(payload) if isinstance(payload, Mapping) else {}


def outcome(spec: EventSpec) -> dict[str, Any]:
    """The data of a feedback, state or error event as a WoT consumer receives it: the event's payload with
    the requester's `correlationId` and the robot's `mission` beside it (error: and the `affordance`)."""
    payload = spec.schema["properties"]["payload"]
    props: dict[str, Any] = {}
    if spec.kind is Kind.ERROR:
        props["affordance"] = {"description": "The affordance the refused or failed request was for.", "type": "string"}
    props[CORRELATION] = {
        "description": "The correlationId the consumer sent with the request this event answers.",
        "type": "string",
    }
    props["mission"] = dict(_MISSION_SCHEMA)
    props.update(payload["properties"])
    return {
        "type": "object",
        "properties": props,
        "required": list(payload["required"]),
        "additionalProperties": False,
    }


def wot_data(spec: EventSpec) -> dict[str, Any]:
    """What travels on `spec`'s WoT topic."""
    if spec.kind in (Kind.INVOKE, Kind.QUERY, Kind.CANCEL):
        return action_input(spec)
    if spec.kind in (Kind.PROPERTY, Kind.WRITE):
        return property_value(spec)
    return outcome(spec)


def wot_specs(catalog: EventCatalog) -> list[EventSpec]:
    """The events with a WoT topic, in catalog order."""
    return [s for s in catalog.specs if s.kind is not Kind.STATUS]
