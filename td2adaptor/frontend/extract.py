"""Read ROS bindings out of a TD, whatever dialect each form speaks, into one raw record per affordance.

Two form dialects are understood side by side (per form, so a TD may mix them while migrating):
* the td2adaptor binding: `rosv:*` terms (docs/binding.md);
* the reference system's: `ros:serviceName`/`ros:TopicName`/... with `subprotocol: "ros"`, grouped by the
  affordance key `ros:codeGenerator:class`.
Nothing here resolves types or checks names; that is `lower`'s job. The input may be any JSON value:
every access is defensive, so malformed TDs give diagnostics, never exceptions.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from td2adaptor.diagnostics import Diagnostics, pointer_join
from td2adaptor.model import (
    Durability,
    History,
    Interface,
    QoS,
    Reliability,
    Role,
    Text,
    freeze,
)

REFERENCE = "reference"
BINDING = "rosv"

AFFORDANCE_KINDS = ("properties", "actions", "events")
_KIND = {"properties": "property", "actions": "action", "events": "event"}

REFERENCE_SERVICE_KEYS = (
    "ros:serviceName",
    "ros:serviceType",
    "ros:serviceRequestType",
    "ros:serviceResponseType",
)
REFERENCE_TOPIC_KEYS = ("ros:Role", "ros:TopicName", "ros:TopicType", "ros:MessageType")
REFERENCE_CLASS_KEY = "ros:codeGenerator:class"


@dataclass(frozen=True)
class Located:
    """A value read from the TD together with the JSON pointer it came from."""

    value: Any
    pointer: str


@dataclass(frozen=True)
class RawEndpoint:
    """One affordance's ROS binding as written, before names and types are checked and resolved."""

    kind: str  # "property" | "action" | "event"
    name: str
    pointer: str
    dialect: str
    interface: Interface
    role: Role
    ros_name: Located
    type_name: Located  # as written (pkg/srv/Name, pkg/Name or dotted)
    component: Located | None = None
    qos: QoS = QoS()
    procedure: Located | None = None  # rosv:procedure object
    declared: tuple[Located, ...] = ()  # reference dialect: request/response/message class names to cross-check
    text: Text = Text()
    input_schema: Any = None
    output_schema: Any = None
    schema: Any = None
    form_pointer: str = ""
    href: Located | None = None


def obj(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def affordances(td: Any) -> list[tuple[str, str, dict[str, Any], str]]:
    """(kind, name, affordance, pointer) in document order, whatever order the maps appear in."""
    out: list[tuple[str, str, dict[str, Any], str]] = []
    for key, group in obj(td).items():
        if key not in AFFORDANCE_KINDS:
            continue
        for name, aff in obj(group).items():
            if isinstance(aff, dict):
                out.append((_KIND[key], name, aff, pointer_join("", key, name)))
    return out


def form_dialect(form: Mapping[str, Any]) -> str | None:
    if any(isinstance(k, str) and k.startswith("rosv:") for k in form):
        return BINDING
    if any(k in form for k in (*REFERENCE_SERVICE_KEYS, *REFERENCE_TOPIC_KEYS)):
        return REFERENCE
    if form.get("subprotocol") == "ros":
        return REFERENCE
    return None


def ros_forms(aff: Mapping[str, Any], pointer: str) -> list[tuple[int, dict[str, Any], str]]:
    forms = aff.get("forms")
    if not isinstance(forms, list):
        return []
    out = []
    for i, form in enumerate(forms):
        if isinstance(form, dict):
            dialect = form_dialect(form)
            if dialect:
                out.append((i, form, dialect))
    return out


def _text(aff: Mapping[str, Any]) -> Text:
    def s(v: Any) -> str | None:
        return v if isinstance(v, str) else None

    def m(v: Any) -> Any:
        return freeze({k: x for k, x in v.items() if isinstance(x, str)}) if isinstance(v, dict) else freeze({})

    return Text(s(aff.get("title")), s(aff.get("description")), m(aff.get("titles")), m(aff.get("descriptions")))


def extract(td: Any, diags: Diagnostics) -> list[RawEndpoint]:
    """Every affordance with a ROS form, as a RawEndpoint, in TD order."""
    out: list[RawEndpoint] = []
    for kind, name, aff, ptr in affordances(td):
        forms = ros_forms(aff, ptr)
        if not forms:
            continue
        if len(forms) > 1:
            first = forms[0][0]
            for i, _form, _d in forms[1:]:
                diags.error(
                    "ROS402",
                    f"{kind} {name!r} has more than one ROS form; an affordance binds exactly one ROS interface",
                    pointer_join(ptr, "forms", i),
                    f"keep only forms/{first}",
                )
        index, form, dialect = forms[0]
        fptr = pointer_join(ptr, "forms", index)
        reader = _read_binding if dialect == BINDING else _read_reference
        raw = reader(kind, name, aff, ptr, form, fptr, diags)
        if raw is not None:
            out.append(raw)
    return out


def _str_at(form: Mapping[str, Any], key: str, fptr: str, diags: Diagnostics, what: str) -> Located | None:
    value = form.get(key)
    ptr = pointer_join(fptr, key)
    if value is None:
        diags.error("ROS403", f"{what}: form term {key!r} is missing", fptr, f'add "{key}" to the form')
        return None
    if not isinstance(value, str) or not value:
        diags.error("ROS404", f"{what}: {key!r} must be a non-empty string", ptr)
        return None
    return Located(value, ptr)


def _common(kind: str, name: str, aff: Mapping[str, Any], form: Mapping[str, Any], fptr: str) -> dict[str, Any]:
    href = form.get("href")
    return {
        "text": _text(aff),
        "input_schema": freeze(aff.get("input")) if kind == "action" else None,
        "output_schema": freeze(aff.get("output")) if kind == "action" else None,
        "schema": freeze(_property_schema(aff)) if kind != "action" else None,
        "form_pointer": fptr,
        "href": Located(href, pointer_join(fptr, "href")) if "href" in form else None,
    }


_AFFORDANCE_ONLY = frozenset(
    """@type title titles description descriptions forms uriVariables observable readOnly writeOnly input output safe
    idempotent synchronous subscription data dataResponse cancellation""".split()
)


def _property_schema(aff: Mapping[str, Any]) -> dict[str, Any]:
    """A property affordance is also its own data schema: keep only the schema part."""
    if "data" in aff and isinstance(aff.get("data"), dict):  # events carry their payload schema in `data`
        return dict(aff["data"])
    return {k: v for k, v in aff.items() if k not in _AFFORDANCE_ONLY and ":" not in k}


# ---------------------------------------------------------------------------------------------------------
# td2adaptor binding


def _read_binding(
    kind: str,
    name: str,
    aff: Mapping[str, Any],
    ptr: str,
    form: Mapping[str, Any],
    fptr: str,
    diags: Diagnostics,
) -> RawEndpoint | None:
    what = f"{kind} {name!r}"
    default_iface = Interface.SERVICE if kind == "action" else Interface.TOPIC
    iface = default_iface
    iface_raw = form.get("rosv:interface")
    if iface_raw is not None:
        try:
            iface = Interface(iface_raw)
        except ValueError:
            diags.error(
                "ROS405",
                f"{what}: rosv:interface must be 'service', 'topic' or 'action', not {iface_raw!r}",
                pointer_join(fptr, "rosv:interface"),
            )
            return None
    if kind == "action" and iface is Interface.TOPIC:
        diags.error("ROS406", f"{what}: a TD action binds a ROS service (or action), not a topic", fptr)
        return None
    if kind != "action" and iface is not Interface.TOPIC:
        diags.error("ROS406", f"{what}: a TD {kind} binds a ROS topic, not a {iface.value}", fptr)
        return None
    role = _binding_role(kind, aff, form, fptr, iface, what, diags)
    ros_name = _str_at(form, "rosv:name", fptr, diags, what)
    type_name = _str_at(form, "rosv:type", fptr, diags, what)
    component = _component(aff, ptr, "rosv:component", what, diags)
    procedure = None
    if "rosv:procedure" in aff:
        procedure = Located(aff["rosv:procedure"], pointer_join(ptr, "rosv:procedure"))
    qos = _binding_qos(form, fptr, what, diags)
    if role is None or ros_name is None or type_name is None or qos is None:
        return None
    return RawEndpoint(
        kind,
        name,
        ptr,
        BINDING,
        iface,
        role,
        ros_name,
        type_name,
        component,
        qos,
        procedure,
        **_common(kind, name, aff, form, fptr),
    )


def _binding_role(
    kind: str,
    aff: Mapping[str, Any],
    form: Mapping[str, Any],
    fptr: str,
    iface: Interface,
    what: str,
    diags: Diagnostics,
) -> Role | None:
    raw = form.get("rosv:role")
    if raw is None:
        if iface is not Interface.TOPIC:
            return Role.CLIENT
        ops = form.get("op")
        ops = [ops] if isinstance(ops, str) else ops if isinstance(ops, list) else []
        if kind == "property" and ops and all(op == "writeproperty" for op in ops):
            return Role.PUBLISHER
        if kind == "property" and aff.get("writeOnly") is True:
            return Role.PUBLISHER
        return Role.SUBSCRIBER
    try:
        role = Role(raw)
    except ValueError:
        diags.error(
            "ROS407",
            f"{what}: rosv:role must be 'client', 'publisher' or 'subscriber', not {raw!r}",
            pointer_join(fptr, "rosv:role"),
        )
        return None
    if (role is Role.CLIENT) != (iface is not Interface.TOPIC):
        diags.error(
            "ROS407",
            f"{what}: role {role.value!r} does not fit a ROS {iface.value}",
            pointer_join(fptr, "rosv:role"),
            "services and actions are called as 'client'; topics are 'publisher' or 'subscriber'",
        )
        return None
    return role


def _binding_qos(form: Mapping[str, Any], fptr: str, what: str, diags: Diagnostics) -> QoS | None:
    qos = QoS()
    raw = form.get("rosv:qos")
    ok = True
    if raw is not None:
        qptr = pointer_join(fptr, "rosv:qos")
        if not isinstance(raw, dict):
            diags.error("ROS408", f"{what}: rosv:qos must be an object", qptr)
            return None
        values: dict[str, Any] = {}
        for key, enum_type in (
            ("reliability", Reliability),
            ("durability", Durability),
            ("history", History),
        ):
            if key in raw:
                try:
                    values[key] = enum_type(raw[key])
                except ValueError:
                    allowed = ", ".join(repr(e.value) for e in enum_type)
                    diags.error("ROS408", f"{what}: QoS {key} must be one of {allowed}", pointer_join(qptr, key))
                    ok = False
        if "depth" in raw:
            if _positive_int(raw["depth"]):
                values["depth"] = raw["depth"]
            else:
                diags.error("ROS408", f"{what}: QoS depth must be a positive integer", pointer_join(qptr, "depth"))
                ok = False
        for key in raw:
            if key not in ("reliability", "durability", "history", "depth"):
                diags.error(
                    "ROS408",
                    f"{what}: unknown QoS policy {key!r}",
                    pointer_join(qptr, key),
                    "known policies: reliability, durability, history, depth",
                )
                ok = False
        qos = QoS(**{**qos.__dict__, **values})
    if "rosv:latch" in form:
        if isinstance(form["rosv:latch"], bool):
            qos = QoS(**{**qos.__dict__, "latch": form["rosv:latch"]})
        else:
            diags.error("ROS408", f"{what}: rosv:latch must be true or false", pointer_join(fptr, "rosv:latch"))
            ok = False
    if "rosv:queueSize" in form:
        q = form["rosv:queueSize"]
        if isinstance(q, int) and not isinstance(q, bool) and 0 <= q <= 100000:
            qos = QoS(**{**qos.__dict__, "queue_size": q})
        else:
            diags.error(
                "ROS408",
                f"{what}: rosv:queueSize must be an integer from 0 to 100000",
                pointer_join(fptr, "rosv:queueSize"),
            )
            ok = False
    return qos if ok else None


def _positive_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 100000


def _component(aff: Mapping[str, Any], ptr: str, key: str, what: str, diags: Diagnostics) -> Located | None:
    if key not in aff:
        return None
    value = aff[key]
    cptr = pointer_join(ptr, key)
    if not isinstance(value, str) or not value:
        diags.error("ROS409", f"{what}: {key} must be a non-empty string (the component class name)", cptr)
        return None
    return Located(value, cptr)


# ---------------------------------------------------------------------------------------------------------
# reference (BRAIN-IoT ROS Edge Node) dialect


def _read_reference(
    kind: str,
    name: str,
    aff: Mapping[str, Any],
    ptr: str,
    form: Mapping[str, Any],
    fptr: str,
    diags: Diagnostics,
) -> RawEndpoint | None:
    what = f"{kind} {name!r}"
    if form.get("contentType") == "application/xml":
        diags.warning(
            "ROS415",
            f"{what}: contentType 'application/xml' but the data is not XML (reference-dialect defect)",
            pointer_join(fptr, "contentType"),
            "remove it: the default application/json describes the JSON data schemas",
        )
    component = _component(aff, ptr, REFERENCE_CLASS_KEY, what, diags)
    common = _common(kind, name, aff, form, fptr)
    if kind == "action":
        ros_name = _str_at(form, "ros:serviceName", fptr, diags, what)
        type_name = _str_at(form, "ros:serviceType", fptr, diags, what)
        declared = tuple(
            Located(form[k], pointer_join(fptr, k))
            for k in ("ros:serviceRequestType", "ros:serviceResponseType")
            if isinstance(form.get(k), str)
        )
        if ros_name is None or type_name is None:
            return None
        return RawEndpoint(
            kind,
            name,
            ptr,
            REFERENCE,
            Interface.SERVICE,
            Role.CLIENT,
            ros_name,
            type_name,
            component,
            declared=declared,
            **common,
        )
    role_raw = form.get("ros:Role", "Subscriber")
    roles = {"subscriber": Role.SUBSCRIBER, "publisher": Role.PUBLISHER}
    role = roles.get(role_raw.lower()) if isinstance(role_raw, str) else None
    if role is None:
        diags.error(
            "ROS407",
            f"{what}: ros:Role must be 'Subscriber' or 'Publisher', not {role_raw!r}",
            pointer_join(fptr, "ros:Role"),
        )
        return None
    ros_name = _str_at(form, "ros:TopicName", fptr, diags, what)
    type_name = _str_at(form, "ros:TopicType", fptr, diags, what)
    declared = (
        (Located(form["ros:MessageType"], pointer_join(fptr, "ros:MessageType")),)
        if isinstance(form.get("ros:MessageType"), str)
        else ()
    )
    if ros_name is None or type_name is None:
        return None
    # The reference generator latched every publisher (rosjava `setLatchMode(true)`).
    qos = QoS(latch=True, durability=Durability.TRANSIENT_LOCAL, depth=1) if role is Role.PUBLISHER else QoS()
    return RawEndpoint(
        kind,
        name,
        ptr,
        REFERENCE,
        Interface.TOPIC,
        role,
        ros_name,
        type_name,
        component,
        qos,
        declared=declared,
        **common,
    )
