"""The canonical model: what every backend consumes, whatever the input dialect was.

Frozen dataclasses, tuples in TD order, JSON data frozen into read-only mappings. Source pointers are kept
for diagnostics but excluded from equality, so a TD and its migrated form compile to equal models.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

# ---------------------------------------------------------------------------------------------------------
# JSON values, frozen


class FrozenMap(dict[str, Any]):
    """A read-only dict that, unlike `types.MappingProxyType`, pickles (for the result cache)."""

    def _readonly(self, *_args: Any, **_kwargs: Any) -> Any:
        raise TypeError("the canonical model is immutable")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = __ior__ = _readonly

    def __reduce__(self) -> tuple[Any, ...]:
        return (FrozenMap, (dict(self),))


def freeze(value: Any) -> Any:
    """Deep-freeze JSON data: dicts become read-only mappings, lists become tuples."""
    if isinstance(value, Mapping):
        return FrozenMap({k: freeze(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(freeze(v) for v in value)
    return value


def thaw(value: Any) -> Any:
    """Inverse of `freeze`: plain dicts and lists again (for JSON output)."""
    if isinstance(value, Mapping):
        return {k: thaw(v) for k, v in value.items()}
    if isinstance(value, tuple):
        return [thaw(v) for v in value]
    return value


# ---------------------------------------------------------------------------------------------------------
# ROS interface types (resolved definitions)


class ArrayKind(str, enum.Enum):
    NONE = "none"
    FIXED = "fixed"  # T[N]
    SEQUENCE = "sequence"  # T[] (bound 0) or T[<=N]


@dataclass(frozen=True)
class FieldType:
    """The type of one message field.

    `base` is a primitive (`bool`, `int32`, `float64`, `string`, `time`, ...) or a message name in canonical
    `pkg/msg/Name` form (`is_message`). `length` is N for fixed arrays and the bound of bounded sequences
    (0 = unbounded); `string_bound` is N for `string<=N`.
    """

    base: str
    is_message: bool = False
    array: ArrayKind = ArrayKind.NONE
    length: int = 0
    string_bound: int = 0

    def __str__(self) -> str:
        s = self.base
        if self.string_bound:
            s += f"<={self.string_bound}"
        if self.array is ArrayKind.FIXED:
            s += f"[{self.length}]"
        elif self.array is ArrayKind.SEQUENCE:
            s += f"[<={self.length}]" if self.length else "[]"
        return s


@dataclass(frozen=True)
class MessageField:
    name: str
    type: FieldType
    default: Any = None  # ROS 2 default value from the definition, if any
    #: the field's comment in its interface file (the comment lines right above it and its trailing comment);
    #: "" from a type store. Text only: not part of equality or hash, so it changes no definition or md5.
    comment: str = field(default="", compare=False)


@dataclass(frozen=True)
class Constant:
    name: str
    type: str
    value: Any


@dataclass(frozen=True)
class MessageDef:
    """One message (or one half of a service/action) in canonical `pkg/msg/Name` / `pkg/srv/Name_Request`."""

    name: str
    fields: tuple[MessageField, ...]
    constants: tuple[Constant, ...] = ()
    origin: str = field(default="", compare=False)  # typestore or file it came from

    @property
    def package(self) -> str:
        return self.name.split("/", 1)[0]

    @property
    def short_name(self) -> str:
        return self.name.rsplit("/", 1)[-1]


@dataclass(frozen=True)
class ServiceDef:
    name: str  # pkg/srv/Name
    request: MessageDef
    response: MessageDef

    @property
    def package(self) -> str:
        return self.name.split("/", 1)[0]


@dataclass(frozen=True)
class ActionDef:
    name: str  # pkg/action/Name
    goal: MessageDef
    result: MessageDef
    feedback: MessageDef


@dataclass(frozen=True)
class Ros1Digest:
    """ROS 1 wire identity of a message or service: full definition text (as in connection headers) and md5."""

    name: str
    definition: str
    md5: str


@dataclass(frozen=True)
class TypeTable:
    """Every interface type a model uses, resolved for one ROS distribution, in first-use order."""

    distro: str  # "ros1" (Noetic rules) or "ros2" (Jazzy)
    messages: tuple[MessageDef, ...] = ()
    services: tuple[ServiceDef, ...] = ()
    actions: tuple[ActionDef, ...] = ()
    missing: tuple[str, ...] = ()  # names that did not resolve for this distro
    ros1_digests: tuple[Ros1Digest, ...] = ()  # ros1 tables: every message and service above
    #: (type the TD binds, why this distro cannot use it) for each such type that the other distro can use:
    #: a backend of this distro names the reason instead of only the missing name
    unavailable: tuple[tuple[str, str], ...] = ()

    def ros1_digest(self, name: str) -> Ros1Digest:
        return next(d for d in self.ros1_digests if d.name == name)

    def why_unavailable(self, name: str) -> str | None:
        """Why this distro cannot use `name`, a type the TD binds (None when it can, or nobody said why)."""
        return next((why for type_name, why in self.unavailable if type_name == name), None)

    @cached_property
    def _by_name(self) -> dict[str, Any]:
        table: dict[str, Any] = {m.name: m for m in self.messages}
        table.update({s.name: s for s in self.services})
        table.update({m.name: m for s in self.services for m in (s.request, s.response)})
        table.update({a.name: a for a in self.actions})
        table.update({m.name: m for a in self.actions for m in (a.goal, a.result, a.feedback)})
        return table

    def message(self, name: str) -> MessageDef:
        found = self._by_name[name]
        assert isinstance(found, MessageDef)
        return found

    def service(self, name: str) -> ServiceDef:
        found = self._by_name[name]
        assert isinstance(found, ServiceDef)
        return found

    def action(self, name: str) -> ActionDef:
        found = self._by_name[name]
        assert isinstance(found, ActionDef)
        return found

    def get(self, name: str) -> MessageDef | ServiceDef | ActionDef | None:
        found: MessageDef | ServiceDef | ActionDef | None = self._by_name.get(name)
        return found

    def primitive_at(self, msg: MessageDef, path: Sequence[str]) -> str | None:
        """The primitive type of the field at `path` (field names, through nested messages, no arrays on the
        way) in `msg`, or None when there is none: the one walk of a field path every stage reads."""
        current: MessageDef | None = msg
        for i, part in enumerate(path):
            found = next((f for f in current.fields if f.name == part), None) if current is not None else None
            if found is None or found.type.array is not ArrayKind.NONE:
                return None
            if i == len(path) - 1:
                return None if found.type.is_message else found.type.base
            inner = self.get(found.type.base) if found.type.is_message else None
            current = inner if isinstance(inner, MessageDef) else None
        return None

    @property
    def complete(self) -> bool:
        return not self.missing


# ---------------------------------------------------------------------------------------------------------
# ROS graph side


@dataclass(frozen=True)
class RosName:
    """A ROS graph name, possibly under the robot namespace.

    `namespaced` names are written `/{{robotName}}/rest` (td2adaptor binding) or `/#robotName/rest`
    (reference dialect); `path` is then `rest`. Other names are kept verbatim in `path`.
    """

    path: str
    namespaced: bool = False

    def resolve(self, namespace: str = "") -> str:
        if not self.namespaced:
            return self.path
        ns = namespace.strip("/")
        return f"/{ns}/{self.path}" if ns else f"/{self.path}"

    def binding_form(self) -> str:
        """How the td2adaptor binding writes this name."""
        return f"/{{{{robotName}}}}/{self.path}" if self.namespaced else self.path


class Interface(str, enum.Enum):
    SERVICE = "service"
    TOPIC = "topic"
    ACTION = "action"  # ROS 2 actions (rclpy backend); ROS 1 actionlib is not generated yet


class Role(str, enum.Enum):
    CLIENT = "client"
    PUBLISHER = "publisher"
    SUBSCRIBER = "subscriber"


class ProcedureRole(str, enum.Enum):
    NONE = "none"
    RUN = "run"
    QUERY = "query"
    CANCEL = "cancel"


class Reliability(str, enum.Enum):
    RELIABLE = "reliable"
    BEST_EFFORT = "best_effort"


class Durability(str, enum.Enum):
    VOLATILE = "volatile"
    TRANSIENT_LOCAL = "transient_local"


class History(str, enum.Enum):
    KEEP_LAST = "keep_last"
    KEEP_ALL = "keep_all"


@dataclass(frozen=True)
class QoS:
    """Topic quality of service. ROS 2 uses reliability/durability/history/depth; ROS 1 latch/queue size."""

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 10
    latch: bool = False
    queue_size: int = 10


@dataclass(frozen=True)
class Text:
    """Human text of an affordance: title/description plus their language maps."""

    title: str | None = None
    description: str | None = None
    titles: Mapping[str, str] = field(default_factory=FrozenMap)
    descriptions: Mapping[str, str] = field(default_factory=FrozenMap)


class Failure(str, enum.Enum):
    """How a service's response says that the robot failed (the lowering reads it from the response type).

    RESULT: procedures_msgs style, `result.result == "error"` with `result.message`; SUCCESS: std_srvs style,
    `success` false with `message`; SUCCESS_ONLY: `success` false and no message field; NONE: it cannot say.
    """

    NONE = "none"
    RESULT = "result"
    SUCCESS = "success"
    SUCCESS_ONLY = "success_only"


@dataclass(frozen=True)
class ServiceEndpoint:
    """A TD action bound to a ROS service, called by the adaptor (client side)."""

    name: str  # the affordance key, e.g. "gotoRun"
    ros_name: RosName
    type_name: str  # canonical pkg/srv/Name
    text: Text = Text()
    procedure_role: ProcedureRole = ProcedureRole.NONE
    input_schema: Any = None  # frozen JSON
    output_schema: Any = None
    pointer: str = field(default="", compare=False)
    #: how its response says the robot failed, in every ROS version that defines the type
    failure: Failure = Failure.NONE


@dataclass(frozen=True)
class ActionEndpoint:
    """A TD action bound to a ROS 2 action (`"rosv:interface": "action"`), a goal sent by the adaptor (client).

    `input_schema` describes the goal, `output_schema` the result; the feedback has no TD schema."""

    name: str  # the affordance key, e.g. "fibonacci"
    ros_name: RosName
    type_name: str  # canonical pkg/action/Name
    text: Text = Text()
    input_schema: Any = None  # frozen JSON
    output_schema: Any = None
    pointer: str = field(default="", compare=False)


@dataclass(frozen=True)
class TopicEndpoint:
    """A TD property bound to a ROS topic, subscribed or published by the adaptor."""

    name: str
    ros_name: RosName
    type_name: str  # canonical pkg/msg/Name
    role: Role
    qos: QoS = QoS()
    text: Text = Text()
    schema: Any = None
    pointer: str = field(default="", compare=False)


@dataclass(frozen=True)
class Procedure:
    """A long-running robot procedure: the run action and the actions that query and cancel it.

    `mission_id` is the response field path (e.g. ("state", "header", "id")) holding the id the robot assigns.
    How a state is read from a response: with `state` (a field path) through `states` (field value as text →
    queued/running/paused/finished/failed/cancelled) and `message` (a field path), or, when `state` is empty,
    by the procedures_msgs convention (state/current_state, state/last_event, result/result, result/message).
    `stateful` names the roles ("run", "query", "cancel") whose responses carry a state that way; the
    others only say that the call was taken. `slots` says, per role ("query", "cancel"), the request field path
    that carries the mission id (see `slot`); a role without one cannot name the mission.
    """

    run: str
    query: str | None = None
    cancel: str | None = None
    mission_id: tuple[str, ...] = ()
    state: tuple[str, ...] = ()
    states: tuple[tuple[str, str], ...] = ()
    message: tuple[str, ...] = ()
    stateful: frozenset[str] = frozenset()
    slots: tuple[tuple[str, tuple[str, ...]], ...] = ()

    def slot(self, role: str) -> tuple[str, ...]:
        """The request field path of `role` ("query", "cancel") that takes the mission id; () when none does."""
        return next((path for r, path in self.slots if r == role), ())


@dataclass(frozen=True)
class Component:
    """One generated class: services, topics and actions grouped by the TD."""

    name: str
    services: tuple[ServiceEndpoint, ...] = ()
    topics: tuple[TopicEndpoint, ...] = ()
    procedures: tuple[Procedure, ...] = ()
    actions: tuple[ActionEndpoint, ...] = ()

    @property
    def subscribers(self) -> tuple[TopicEndpoint, ...]:
        return tuple(t for t in self.topics if t.role is Role.SUBSCRIBER)

    @property
    def publishers(self) -> tuple[TopicEndpoint, ...]:
        return tuple(t for t in self.topics if t.role is Role.PUBLISHER)

    def service(self, name: str) -> ServiceEndpoint:
        return next(s for s in self.services if s.name == name)

    def procedure_of(self, action: str) -> Procedure | None:
        return next((p for p in self.procedures if action in (p.run, p.query, p.cancel)), None)


@dataclass(frozen=True)
class Thing:
    """Thing-level metadata that generated packages carry."""

    title: str
    id: str | None = None
    description: str | None = None
    version: str | None = None
    master_uri: str | None = None
    security: Any = None  # frozen securityDefinitions of the Thing, for the runtime
    #: the Thing Model this Thing is an instance of: the href of the TD's `rel: type` link (an instantiated
    #: model's file name); a robot's exposed TD links it too
    model: str | None = None
    #: whether `description` is the Thing Model's (the TD was instantiated from one here), which describes the
    #: model ("instantiate it per robot ...") rather than any one robot
    model_description: bool = False


@dataclass(frozen=True)
class Model:
    thing: Thing
    package_name: str
    components: tuple[Component, ...]
    ros1: TypeTable
    ros2: TypeTable
    #: interface packages the adaptors import that come from the standard sets, not the user's interface
    #: folders: the robot's software installs them (ROS 2 wheel ros-jazzy-<pkg>, Debian python3-<pkg>)
    standard_packages: tuple[str, ...] = ()

    @property
    def namespaced(self) -> bool:
        """Whether any ROS name lives under the robot namespace (constructors then take one)."""
        services = any(s.ros_name.namespaced for c in self.components for s in c.services)
        actions = any(a.ros_name.namespaced for c in self.components for a in c.actions)
        return services or actions or any(t.ros_name.namespaced for c in self.components for t in c.topics)

    def types_for(self, distro: str) -> TypeTable:
        return self.ros1 if distro == "ros1" else self.ros2

    def component(self, name: str) -> Component:
        return next(c for c in self.components if c.name == name)

    def unusable(self, distro: str) -> list[tuple[str, ServiceEndpoint | TopicEndpoint | ActionEndpoint, str]]:
        """Every affordance whose type `distro` cannot use although the other version can, in TD order:
        (what the TD calls it, e.g. "action 'navigate'", the endpoint, why): a backend refusing them says why."""
        table = self.types_for(distro)
        found: list[tuple[str, ServiceEndpoint | TopicEndpoint | ActionEndpoint, str]] = []
        for comp in self.components:
            endpoints: tuple[ServiceEndpoint | TopicEndpoint | ActionEndpoint, ...] = (
                *comp.services,
                *comp.actions,
                *comp.topics,
            )
            for ep in endpoints:
                why = table.why_unavailable(ep.type_name)
                if why is not None:
                    kind = "property" if isinstance(ep, TopicEndpoint) else "action"
                    found.append((f"{kind} {ep.name!r}", ep, why))
        return found
