"""The events an adaptor consumes and emits, derived from the canonical model.

One catalog serves both the `events` backend (which writes the schemas, the AsyncAPI document and the exposed
TD) and the runtime (which validates and routes with the very same schemas), so the two cannot drift apart.

Topic scheme (every level but the robot id is a validated identifier, so no level can contain `/`, `+`, `#`):

    td2adaptor/<robot>/<Component>/<action>            invoke (run or plain action), query, cancel  (in)
    td2adaptor/<robot>/<Component>/<property>/write    write a publisher property                   (in)
    td2adaptor/<robot>/<Component>/<property>          property value, retained, throttled          (out)
    td2adaptor/<robot>/<Component>/<run>/feedback      every state change of a mission              (out)
    td2adaptor/<robot>/<Component>/<run>/state         answer to a query or cancel event            (out)
    td2adaptor/<robot>/<Component>/<action>/query      query a ROS action's goal                    (in)
    td2adaptor/<robot>/<Component>/<action>/cancel     cancel a ROS action's goal                   (in)
    td2adaptor/<robot>/error                           error events                                 (out)
    td2adaptor/<robot>/status                          online/offline, presence, owner; retained, will (out)
    td2adaptor/<robot>/td                              the robot's Thing Description, retained      (out)

The last one is no event: the edge node publishes there the robot's TD (what `td2adaptor expose` writes) as
soon as it is online and clears it (an empty retained message) when it stops.

`<robot>` is the robot id; the reserved id `all` addresses every robot (inbound events only).

A TD action bound to a ROS action is a procedure by nature (see `_goal_events`): its invoke sends a goal,
its feedback events carry the ROS feedback messages and end with the result, and since the ROS action has
no affordances of its own for query and cancel, they are topics under the action's.
"""

from __future__ import annotations

import enum
import re
import threading
import weakref
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

from td2adaptor.model import (
    ActionDef,
    ActionEndpoint,
    Component,
    Model,
    ProcedureRole,
    Role,
    ServiceEndpoint,
    Text,
    TopicEndpoint,
    thaw,
)
from td2adaptor.model.msgschema import message_schema, strictest

TOPIC_ROOT = "td2adaptor"
ALL_ROBOTS = "all"
#: robot ids: one MQTT topic level, readable in logs; `all` is reserved for the all-robots channel
ROBOT_ID = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]{0,127}$")
ROBOT_ID_PATTERN = ROBOT_ID.pattern
SCHEMA_BASE = "https://td2adaptor.dev/events/"
#: the topic level under which each robot's edge node keeps its Thing Description (retained)
TD_LEVEL = "td"
DRAFT = "https://json-schema.org/draft/2020-12/schema"
_TIME_PATTERN = r"^\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(\.\d{1,9})?(Z|[+-]\d{2}:\d{2})$"


class Kind(str, enum.Enum):
    INVOKE = "invoke"
    QUERY = "query"
    CANCEL = "cancel"
    WRITE = "write"
    FEEDBACK = "feedback"
    STATE = "state"
    PROPERTY = "property"
    ERROR = "error"
    STATUS = "status"

    @property
    def inbound(self) -> bool:
        return self in (Kind.INVOKE, Kind.QUERY, Kind.CANCEL, Kind.WRITE)


#: procedure states a feedback or state event reports; the last three are terminal
STATES = ("queued", "running", "paused", "finished", "failed", "cancelled")
TERMINAL_STATES = frozenset({"finished", "failed", "cancelled"})
#: why a mission failed (feedback `reason`)
FAILURE_REASONS = ("rejected", "busy", "timeout", "unreachable", "call-failed", "aborted", "robot-error")
#: error event codes
ERROR_CODES = (
    "invalid-json",
    "invalid-event",
    "too-large",
    "unknown-topic",
    "busy",
    "call-failed",
    "unsupported",
    "internal",
    "expired",
    "from-the-future",
    "id-reused",
    "no-id-or-time",
    "retained",
    "absent",
)


@dataclass(frozen=True)
class EventSpec:
    """One kind of event for one affordance (or for the robot as a whole: `component` is None)."""

    kind: Kind
    component: str | None
    affordance: str | None  # the TD affordance; for feedback/state the run action
    schema: Mapping[str, Any]
    title: str
    description: str
    run: str | None = None  # query/cancel: the run action they belong to

    @property
    def goal_control(self) -> bool:
        """A query or cancel of a ROS action's goal: it has the action's name, under a topic of its own."""
        return self.kind in (Kind.QUERY, Kind.CANCEL) and self.run is not None and self.run == self.affordance

    @property
    def key(self) -> str:
        """A stable identifier, usable as an AsyncAPI component key."""
        parts = [p for p in (self.component, self.affordance) if p]
        return ".".join([*parts, self.kind.value])

    @property
    def schema_file(self) -> str:
        """Path of the file holding the schema, relative to the package's folder of the events output
        (`OUT/events/<package>/`, what the `$id`s below `EventCatalog.base` mirror): one file per component
        (its events in `$defs`), one per robot-level event. Component names have no `.`, so a component
        called `error` or `envelope` cannot collide with the robot-level files."""
        if self.component is None:
            return f"schemas/{self.kind.value}.schema.json"
        return f"schemas/{self.component}.events.schema.json"

    @property
    def def_name(self) -> str:
        """The schema's name in its component file's `$defs`: `<affordance>.<kind>`."""
        return f"{self.affordance}.{self.kind.value}"

    @property
    def schema_ref(self) -> str:
        """`schema_file` with the JSON pointer to the schema inside it (what `$ref`s and links use)."""
        if self.component is None:
            return self.schema_file
        return f"{self.schema_file}#/$defs/{self.def_name}"

    def topic(self, robot: str, root: str = TOPIC_ROOT) -> str:
        if self.component is None:
            return f"{root}/{robot}/{self.kind.value}"
        base = f"{root}/{robot}/{self.component}/{self.affordance}"
        if self.kind in (Kind.WRITE, Kind.FEEDBACK, Kind.STATE) or self.goal_control:
            return f"{base}/{self.kind.value}"
        return base


@dataclass(frozen=True)
class EventCatalog:
    """Every event of one model, in TD order, plus the shared envelope schema."""

    package: str
    specs: tuple[EventSpec, ...]
    envelope: Mapping[str, Any]
    distro: str = "ros2"  # whose message layouts the payload schemas follow (time: secs/nsecs or sec/nanosec)

    @property
    def base(self) -> str:
        return f"{SCHEMA_BASE}{self.package}/"

    def inbound(self) -> Iterator[EventSpec]:
        return (s for s in self.specs if s.kind.inbound)

    def find(self, kind: Kind, affordance: str | None = None) -> EventSpec:
        """The first spec of `kind` for `affordance`; StopIteration when there is none (as `next` raises).

        Looked up in an index: a scan per call made generating a 10,000-affordance TD quadratic."""
        found = self._first.get((kind, affordance))
        if found is None:
            raise StopIteration
        return found

    @cached_property
    def _first(self) -> dict[tuple[Kind, str | None], EventSpec]:
        index: dict[tuple[Kind, str | None], EventSpec] = {}
        for spec in self.specs:
            index.setdefault((spec.kind, spec.affordance), spec)
        return index

    def uri(self, spec: EventSpec) -> str:
        """The absolute URI of `spec`'s schema (a `$ref` to it validates an event)."""
        return self.base + spec.schema_ref

    @cached_property
    def files(self) -> tuple[tuple[str, Mapping[str, Any]], ...]:
        """(path, schema document) of every schema file, envelope first, then in TD order.

        A component's events share one file, each under `$defs/<affordance>.<kind>`: a large Thing gets one
        file per component instead of one per event (1,000 affordances: 250 files, not 1,500).
        """
        out: list[tuple[str, Mapping[str, Any]]] = [("schemas/envelope.schema.json", self.envelope)]
        bundles: dict[str, dict[str, Any]] = {}
        for spec in self.specs:
            if spec.component is None:
                out.append((spec.schema_file, spec.schema))
                continue
            bundle = bundles.get(spec.schema_file)
            if bundle is None:
                bundle = {
                    "$schema": DRAFT,
                    "$id": self.base + spec.schema_file,
                    "title": f"{spec.component} events",
                    "description": f"The events of {spec.component}, each in $defs as <affordance>.<kind>.",
                    "$defs": {},
                }
                bundles[spec.schema_file] = bundle
                out.append((spec.schema_file, bundle))
            bundle["$defs"][spec.def_name] = spec.schema
        return tuple(out)

    def resources(self) -> list[tuple[str, Mapping[str, Any]]]:
        """(`$id`, document) of every schema file: what a JSON Schema registry needs."""
        return [(str(doc["$id"]), doc) for _, doc in self.files]

    @cached_property
    def _routes(self) -> dict[tuple[str, ...], EventSpec]:
        return {tuple(s.topic("+").split("/")[2:]): s for s in self.inbound()}

    def route(self, topic: str, root: str = TOPIC_ROOT) -> tuple[EventSpec, str] | None:
        """The inbound event spec and robot id (possibly `all`) a topic addresses, or None."""
        levels = topic.split("/")
        if len(levels) < 4 or levels[0] != root:
            return None
        spec = self._routes.get(tuple(levels[2:]))
        return None if spec is None else (spec, levels[1])


#: the levels under `<Component>/<affordance>` where commands arrive (the others carry what the node sends)
COMMAND_SUFFIXES = (Kind.WRITE.value, Kind.QUERY.value, Kind.CANCEL.value)


def command_filters(catalog: EventCatalog, robot: str, root: str = TOPIC_ROOT) -> list[str]:
    """The MQTT filters on which `robot`'s edge node takes its commands: every topic a command can come on, also
    for an affordance (or component) the robot does not have, so that such a command is answered
    (`unknown-topic`) rather than lost. `<Component>/<affordance>` (invokes, queries, cancels; also where the
    node publishes property values, which it drops on arrival) and, per component, `<affordance>/write`,
    `/query` and `/cancel`, not `+/+/write`: that filter would also match a WoT topic (`wot-thing/<C>/write`),
    and a broker may deliver a message once per matching filter. Never the node's feedback and state topics."""
    base = f"{root}/{robot}"
    components = dict.fromkeys(s.component for s in catalog.specs if s.component)
    return [f"{base}/+/+", *(f"{base}/{c}/+/{suffix}" for c in components for suffix in COMMAND_SUFFIXES)]


def td_topic(robot: str, root: str = TOPIC_ROOT) -> str:
    """Where robot `robot`'s edge node keeps its Thing Description, retained, while it runs."""
    return f"{root}/{robot}/{TD_LEVEL}"


# ---------------------------------------------------------------------------------------------------------
# schemas

_SCHEMA_MAPS = ("properties", "patternProperties", "$defs", "definitions", "dependentSchemas")
_SCHEMA_ONE = (
    "items",
    "additionalItems",
    "additionalProperties",
    "unevaluatedItems",
    "unevaluatedProperties",
    "contains",
    "propertyNames",
    "not",
    "if",
    "then",
    "else",
)
_SCHEMA_LISTS = ("allOf", "anyOf", "oneOf", "prefixItems")


def data_schema(value: Any) -> Any:
    """A TD data schema as a self-contained JSON Schema: thawed, with `$`- and `@`-keywords dropped.

    TD data schemas have no references; dropping `$ref`/`$id`/... keeps a hostile TD from pointing a validator
    at the network or redefining our schema ids, and JSON-LD keys (`@type`) mean nothing to JSON Schema.
    """
    value = thaw(value)
    if isinstance(value, bool):
        return value
    if not isinstance(value, dict):
        return {}
    out: dict[str, Any] = {}
    for key, sub in value.items():
        if key.startswith(("$", "@")):
            continue
        if key in _SCHEMA_MAPS and isinstance(sub, dict):
            out[key] = {name: data_schema(s) for name, s in sub.items()}
        elif key in _SCHEMA_ONE:
            out[key] = data_schema(sub) if isinstance(sub, (dict, bool)) else sub
        elif key in _SCHEMA_LISTS and isinstance(sub, list):
            out[key] = [data_schema(s) for s in sub]
        else:
            out[key] = sub
    return typed(out)


def json_type(value: Any) -> str:
    """The JSON Schema type of a JSON value (`integer` for whole numbers written without a fraction)."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    return "array" if isinstance(value, list) else "object"


def typed(schema: dict[str, Any]) -> dict[str, Any]:
    """`schema` with a `type` wherever it has `const` or `enum` but none (consumers such as wotpy 0.18 need one).

    The type is the values' own; an `enum` mixing types becomes an `anyOf` of one typed `enum` per type (a TD
    data schema's `type` is a single name), integers joining numbers."""
    if "type" in schema or ("const" not in schema and not isinstance(schema.get("enum"), list)):
        return schema
    values = [schema["const"]] if "const" in schema else list(schema["enum"])
    types = list(dict.fromkeys(json_type(v) for v in values))
    if "number" in types and "integer" in types:
        types.remove("integer")
    if len(types) <= 1:
        return {**schema, "type": types[0] if types else "null"}
    groups = [
        {"type": t, "enum": [v for v in values if json_type(v) == t or (t == "number" and json_type(v) == "integer")]}
        for t in types
    ]
    out = {k: v for k, v in schema.items() if k != "enum"}
    if "anyOf" in out:
        out["allOf"] = [*out.get("allOf", []), {"anyOf": groups}]
    else:
        out["anyOf"] = groups
    return out


def _ros_schema(model: Model, type_name: str, half: str = "", *, distro: str, complete: bool) -> dict[str, Any]:
    """JSON Schema of a message (or a service half) in `distro`'s layout, else in the other's when only that
    resolves it; `{}` when neither does. `complete`: every field required (a value the robot sends)."""
    tables = (model.ros1, model.ros2) if distro == "ros1" else (model.ros2, model.ros1)
    for table in tables:
        found = table.get(type_name)
        if found is None:
            continue
        if half:
            svc = table.service(type_name)
            return message_schema(svc.request if half == "request" else svc.response, table, complete=complete)
        msg = table.message(type_name)
        return message_schema(msg, table, complete=complete)
    return {}


def payload_schema(model: Model, type_name: str, td: Any, *, half: str = "", distro: str, complete: bool) -> Any:
    """A payload's schema: the ROS type's, narrowed by the TD's data schema `td` where it has one; an object
    when neither says more."""
    ros = _ros_schema(model, type_name, half, distro=distro, complete=complete)
    schema = strictest(ros, data_schema(td)) if td is not None else ros
    return schema or {"type": "object"}


def _text(text: Text, fallback: str) -> tuple[str, str]:
    return (text.title or fallback, text.description or "")


def _envelope(base: str) -> dict[str, Any]:
    return {
        "$schema": DRAFT,
        "$id": f"{base}schemas/envelope.schema.json",
        "title": "td2adaptor event envelope",
        "description": (
            "Fields every td2adaptor event shares. Inbound events (invoke, query, cancel, write) may leave out "
            "what their topic already says; events the adaptor emits carry all of type, affordance (where there "
            "is one), robot, id, time and source."
        ),
        "type": "object",
        "properties": {
            "type": {"description": "The kind of event.", "type": "string", "enum": [k.value for k in Kind]},
            "affordance": {
                "description": "The TD affordance the event is about (for feedback and state: the run action).",
                "type": "string",
                "pattern": "^[A-Za-z][A-Za-z0-9_]*$",
            },
            "robot": {
                "description": f"Robot id; {ALL_ROBOTS!r} addresses every robot (inbound events only).",
                "type": "string",
                "pattern": ROBOT_ID_PATTERN,
            },
            "id": {
                "description": "Unique id of this event; redeliveries of an inbound event with the same id are "
                "handled once.",
                "type": "string",
                "minLength": 1,
                "maxLength": 128,
            },
            "correlation": {
                "description": "Chosen by the requester; copied into every event answering it (feedback, state, "
                "error).",
                "type": "string",
                "minLength": 1,
                "maxLength": 256,
            },
            "mission": {
                "description": "Mission id the robot assigned to a procedure run.",
                "type": "integer",
                "minimum": -(2**63),
                "maximum": 2**64 - 1,
            },
            "time": {
                "description": "When the event was created (RFC 3339).",
                "type": "string",
                "format": "date-time",
                "pattern": _TIME_PATTERN,
            },
            "source": {"description": "Who sent the event.", "type": "string", "minLength": 1, "maxLength": 256},
            "payload": {"description": "Event-specific content."},
        },
    }


_OUT_REQUIRED = ["type", "robot", "id", "time", "source", "payload"]
_ENVELOPE_MEMBERS = tuple(_envelope("")["properties"])


def _event_schema(
    base: str,
    path: str | None,
    title: str,
    description: str,
    kind: Kind,
    affordance: str | None,
    payload: Any,
    *,
    required: list[str],
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    # every envelope member by reference, then this event's own constraints in place of the shared ones (each
    # self-sufficient), closed with additionalProperties: the same meaning in JSON Schema draft-07 and
    # 2020-12, so that AsyncAPI tools, which check draft-07 payloads, check these too
    props: dict[str, Any] = {name: {"$ref": f"envelope.schema.json#/properties/{name}"} for name in _ENVELOPE_MEMBERS}
    props["type"] = {"type": "string", "const": kind.value}
    if affordance is not None:
        props["affordance"] = {"type": "string", "const": affordance}
    else:
        props["affordance"] = False
    if not kind.inbound:
        props["robot"] = {"type": "string", "pattern": ROBOT_ID_PATTERN, "not": {"type": "string", "const": ALL_ROBOTS}}
    props.update(extra or {})
    props["payload"] = payload
    # robot-level events are files of their own; a component's events sit in its file's $defs, where the
    # file's $id is the base the (same) relative reference to the envelope resolves against
    head: dict[str, Any] = {} if path is None else {"$schema": DRAFT, "$id": f"{base}{path}"}
    return {
        **head,
        "title": title,
        "description": description,
        "type": "object",
        "properties": props,
        "required": required,
        "additionalProperties": False,
    }


def _state_payload(*, feedback: bool, output: Any = None) -> dict[str, Any]:
    props: dict[str, Any] = {
        "state": {"description": "Procedure state.", "type": "string", "enum": list(STATES)},
        "terminal": {"description": "Whether this is the mission's last event.", "type": "boolean"},
    }
    if feedback:
        props["seq"] = {
            "description": "1, 2, ... per mission: a repeat is a redelivery; a gap is a lost event, or numbers "
            "skipped by an edge node that restarted during a ROS action goal (reserved ahead, never reused).",
            "type": "integer",
            "minimum": 1,
        }
    props.update(
        {
            "result": {"description": "The robot's result code (e.g. ok, error).", "type": "string"},
            "message": {"description": "The robot's or the adaptor's message.", "type": "string"},
            "last_event": {"description": "The robot's last procedure event (e.g. start, finish).", "type": "string"},
            "reason": {"description": "Why the mission failed.", "type": "string", "enum": list(FAILURE_REASONS)},
        }
    )
    if output is not None:
        props["output"] = output
    return {
        "type": "object",
        "properties": props,
        "required": ["state", "terminal", "seq"] if feedback else ["state", "terminal"],
        "additionalProperties": False,
    }


def _error_payload() -> dict[str, Any]:
    return {
        "type": "object",
        "properties": {
            "code": {"type": "string", "enum": list(ERROR_CODES)},
            "message": {"type": "string"},
            "topic": {"description": "Topic the offending event arrived on.", "type": "string"},
            "event": {"description": "The start of the offending event, as text.", "type": "string", "maxLength": 1024},
            "errors": {
                "description": "Schema violations (at most 10).",
                "type": "array",
                "maxItems": 10,
                "items": {
                    "type": "object",
                    "properties": {"path": {"type": "string"}, "message": {"type": "string"}},
                    "required": ["path", "message"],
                    "additionalProperties": False,
                },
            },
        },
        "required": ["code", "message"],
        "additionalProperties": False,
    }


#: the robot's ROS side as its edge node sees it (status `robot`): every server of its affordances there, some,
#: or none
PRESENCE_WORDS = ("present", "partial", "absent")


def _status_payload() -> dict[str, Any]:
    text = {"type": "string", "maxLength": 256}
    return {
        "type": "object",
        "properties": {
            "state": {
                "description": "online: the edge node serves the robot; offline: it stopped, or died (the will).",
                "type": "string",
                "enum": ["online", "offline"],
            },
            "thing": {"description": "Title of the Thing this adaptor serves.", "type": "string"},
            "robot": {
                "description": "While online: whether the servers of the robot's actions are on ROS (present), "
                "some of them (partial) or none (absent: an invoke is refused at once).",
                "type": "string",
                "enum": list(PRESENCE_WORDS),
            },
            "missing": {
                "description": "The actions whose ROS server is not there (at most 32).",
                "type": "array",
                "maxItems": 32,
                "items": text,
            },
            "owner": {
                "description": "The edge-node process that serves (or last served) the robot.",
                "type": "object",
                "properties": {
                    "host": text,
                    "pid": {"type": "integer", "minimum": 0},
                    "started": {"description": "When the process started (RFC 3339).", **text},
                    "node": {"description": "A random id of the process, new at every start.", **text},
                },
                "required": ["host", "pid", "started", "node"],
                "additionalProperties": False,
            },
            "missions": {"description": "Missions in flight.", "type": "integer", "minimum": 0},
            "lastError": {
                "description": "The last error event the edge node published for this robot.",
                "type": "object",
                "properties": {"code": text, "message": {"type": "string", "maxLength": 1024}, "time": text},
                "required": ["code", "message", "time"],
                "additionalProperties": False,
            },
        },
        "required": ["state"],
        "additionalProperties": False,
    }


def _invoke_payload(model: Model, svc: ServiceEndpoint, distro: str) -> tuple[Any, bool]:
    """The payload schema of an invoke event and whether a payload is required."""
    schema = payload_schema(model, svc.type_name, svc.input_schema, half="request", distro=distro, complete=False)
    return schema, svc.input_schema is not None or bool(schema.get("properties"))


def _property_payload(model: Model, topic: TopicEndpoint, distro: str, *, complete: bool) -> Any:
    return payload_schema(model, topic.type_name, topic.schema, distro=distro, complete=complete)


#: catalogs built, by (id of the model, distro), while the model lives: a fleet's robots share their TD's
_CATALOGS: dict[tuple[int, str], EventCatalog] = {}
_CATALOGS_LOCK = threading.Lock()


def build_catalog(model: Model, distro: str = "ros2") -> EventCatalog:
    """Every event of `model`: per component in TD order, then the robot-level error and status events.

    Payloads follow `distro`'s message layouts (the ROS version the robot runs). The same catalog for the same
    model and distro while the model lives (nothing changes a catalog): the robots of a fleet, one TD, share one
    instead of holding a copy each (about 160 KiB per RB-1)."""
    key = (id(model), distro)
    with _CATALOGS_LOCK:
        known = _CATALOGS.get(key)
    if known is not None:
        return known
    catalog = _build_catalog(model, distro)
    with _CATALOGS_LOCK:
        if key not in _CATALOGS:  # another thread may have built it meanwhile: the first one stays
            _CATALOGS[key] = catalog
            weakref.finalize(model, _forget, key)
        return _CATALOGS[key]


def _forget(key: tuple[int, str]) -> None:
    with _CATALOGS_LOCK:
        _CATALOGS.pop(key, None)


def _build_catalog(model: Model, distro: str) -> EventCatalog:
    base = f"{SCHEMA_BASE}{model.package_name}/"
    specs: list[EventSpec] = []

    def add(kind: Kind, component: str | None, affordance: str | None, title: str, description: str, **kw: Any) -> None:
        run = kw.pop("run", None)
        probe = EventSpec(kind, component, affordance, {}, title, description, run)
        path = probe.schema_file if component is None else None  # None: embedded in the component's file
        schema = _event_schema(base, path, title, description, kind, affordance, **kw)
        specs.append(EventSpec(kind, component, affordance, schema, title, description, run))

    for comp in model.components:
        for svc in comp.services:
            title, desc = _text(svc.text, svc.name)
            proc = comp.procedure_of(svc.name)
            role = svc.procedure_role
            if role is ProcedureRole.RUN or proc is None or role is ProcedureRole.NONE:
                payload, needed = _invoke_payload(model, svc, distro)
                add(
                    Kind.INVOKE,
                    comp.name,
                    svc.name,
                    f"{title}: invoke",
                    f"Start {svc.name}. {desc}".strip(),
                    payload=payload,
                    required=["payload"] if needed else [],
                    extra={"mission": False},
                )
                plain = role is not ProcedureRole.RUN
                output = None
                if plain:
                    output = payload_schema(
                        model, svc.type_name, svc.output_schema, half="response", distro=distro, complete=True
                    )
                add(
                    Kind.FEEDBACK,
                    comp.name,
                    svc.name,
                    f"{title}: feedback",
                    f"Every state change of a {svc.name} mission; exactly one has terminal true.",
                    payload=_state_payload(feedback=True, output=output),
                    required=_OUT_REQUIRED + ["affordance"],
                )
                if not plain:
                    add(
                        Kind.STATE,
                        comp.name,
                        svc.name,
                        f"{title}: state",
                        f"The state of a {svc.name} mission, answering a query or cancel event.",
                        payload=_state_payload(feedback=False),
                        required=_OUT_REQUIRED + ["affordance"],
                    )
            elif role in (ProcedureRole.QUERY, ProcedureRole.CANCEL):
                kind = Kind.QUERY if role is ProcedureRole.QUERY else Kind.CANCEL
                verb = "Query the state of" if kind is Kind.QUERY else "Cancel"
                add(
                    kind,
                    comp.name,
                    svc.name,
                    f"{title}: {kind.value}",
                    f"{verb} a {proc.run} mission: the one given by `mission`, else the current or last one. "
                    f"Answered by a {proc.run} state event.",
                    payload=False,
                    required=[],
                    run=proc.run,
                )
        for action in comp.actions:
            _goal_events(model, comp, action, add, distro)
        for topic in comp.topics:
            title, desc = _text(topic.text, topic.name)
            if topic.role is Role.SUBSCRIBER:
                add(
                    Kind.PROPERTY,
                    comp.name,
                    topic.name,
                    f"{title}: value",
                    f"Latest value of {topic.name} (retained; throttled by the runtime). {desc}".strip(),
                    payload=_property_payload(model, topic, distro, complete=True),
                    required=_OUT_REQUIRED + ["affordance"],
                )
            else:
                add(
                    Kind.WRITE,
                    comp.name,
                    topic.name,
                    f"{title}: write",
                    f"Publish a value of {topic.name}. {desc}".strip(),
                    payload=_property_payload(model, topic, distro, complete=False),
                    required=["payload"],
                    extra={"mission": False},
                )
    add(
        Kind.ERROR,
        None,
        None,
        "Error",
        "An inbound event that was refused or failed; correlation and mission are copied when known.",
        payload=_error_payload(),
        required=_OUT_REQUIRED,
        extra={"affordance": {"type": "string"}},
    )
    add(
        Kind.STATUS,
        None,
        None,
        "Status",
        "Whether the adaptor is connected and the robot's ROS side there (retained; the broker publishes offline as "
        "the last will).",
        payload=_status_payload(),
        required=_OUT_REQUIRED,
    )
    return EventCatalog(model.package_name, tuple(specs), _envelope(base), distro)


# ---------------------------------------------------------------------------------------------------------
# TD actions bound to ROS actions

#: a goal id as the events carry it: the goal's UUID in hex (ROS 2), or actionlib's goal id text (ROS 1)
GOAL_ID = {"description": "The ROS goal id the adaptor follows.", "type": "string", "minLength": 1, "maxLength": 256}
#: the ROS goal status words a goal event may carry in `result`
GOAL_WORDS = (
    "pending",
    "rejected",
    "accepted",
    "executing",
    "canceling",
    "succeeded",
    "canceled",
    "aborted",
    "lost",
    "unknown",
)


def _action_part(model: Model, action: ActionEndpoint, part: str, *, distro: str, complete: bool) -> Any:
    """JSON Schema of an action's goal, result or feedback in `distro`'s layout (else the other's), narrowed by
    the TD's input (goal) or output (result) schema as a service's request and response are."""
    ros: dict[str, Any] = {}
    for table in (model.ros1, model.ros2) if distro == "ros1" else (model.ros2, model.ros1):
        found = table.get(action.type_name)
        if isinstance(found, ActionDef):
            ros = message_schema(getattr(found, part), table, complete=complete)
            break
    td = {"goal": action.input_schema, "result": action.output_schema}.get(part)
    schema = strictest(ros, data_schema(td)) if td is not None else ros
    return schema or {"type": "object"}


def _goal_payload(*, feedback: Any = None, output: Any = None) -> dict[str, Any]:
    """A feedback (when `feedback` is given) or state payload of a ROS action goal."""
    schema = _state_payload(feedback=feedback is not None, output=output)
    props = dict(schema["properties"])
    props["goal"] = GOAL_ID
    props["result"] = {
        "description": "The ROS goal status, in the robot's words (e.g. succeeded, aborted, canceled, rejected).",
        "type": "string",
        "enum": list(GOAL_WORDS),
    }
    if feedback is not None:
        props["feedback"] = {**feedback, "description": "One ROS feedback message, as the robot sent it."}
    return {**schema, "properties": props}


def _goal_events(model: Model, comp: Component, action: ActionEndpoint, add: Callable[..., None], distro: str) -> None:
    """The events of a TD action bound to a ROS action: invoke (a goal), feedback (one per ROS feedback
    message, then exactly one terminal event with the result), query and cancel of the goal, state."""
    title, desc = _text(action.text, action.name)
    goal = _action_part(model, action, "goal", distro=distro, complete=False)
    needed = action.input_schema is not None or bool(goal.get("properties"))
    output = _action_part(model, action, "result", distro=distro, complete=True)
    add(
        Kind.INVOKE,
        comp.name,
        action.name,
        f"{title}: invoke",
        f"Send a {action.name} goal. {desc}".strip(),
        payload=goal,
        required=["payload"] if needed else [],
        extra={"mission": False},
    )
    add(
        Kind.FEEDBACK,
        comp.name,
        action.name,
        f"{title}: feedback",
        f"The {action.name} goal accepted, one event per ROS feedback message (in `feedback`), then exactly one "
        "terminal event with the result (in `output`).",
        payload=_goal_payload(
            feedback=_action_part(model, action, "feedback", distro=distro, complete=True), output=output
        ),
        required=_OUT_REQUIRED + ["affordance"],
    )
    control = {
        "type": "object",
        "properties": {"goal": {**GOAL_ID, "description": "The goal; default: the current or last one."}},
        "additionalProperties": False,
    }
    for kind, verb in ((Kind.QUERY, "Query the state of"), (Kind.CANCEL, "Cancel")):
        add(
            kind,
            comp.name,
            action.name,
            f"{title}: {kind.value}",
            f"{verb} a {action.name} goal: the one given by `goal`, else the current or last one. Answered by a "
            f"{action.name} state event.",
            payload=control,
            required=[],
            run=action.name,
            extra={"mission": False},
        )
    add(
        Kind.STATE,
        comp.name,
        action.name,
        f"{title}: state",
        f"The state of a {action.name} goal, answering a query or cancel event.",
        payload=_goal_payload(),
        required=_OUT_REQUIRED + ["affordance"],
    )
