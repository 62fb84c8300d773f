"""mROS backend: an embedded C++98 adaptor (mROS v1.3 API, TOPPERS/ASP + Mbed on Cortex-A9) speaking ROS 1.

Output, under `<package>/` (an mROS application directory, to be placed at `mros_ws/<package>/`):

* `app.cpp` (C++98 task bodies), `app.h` (`extern "C"` task entries), `app.cfg` (`CRE_TSK`/`CRE_SEM`),
  `mros_config/` (task table, task count and memory pools consistent with `app.cfg`; see `mros_lint`;
  network settings), a `Makefile` like those of mROS's examples and `README.md`: copied unedited to
  `mros_ws/<package>/` of an mROS v1.3 tree, `make` builds `asp.bin` with the tree's own makefiles;
* `include/<pkg>/<Type>.h`, one class per ROS 1 message type the topics need (transitively): fields,
  `dataSize`/`memCopy`/`deserialize` in the ROS 1 wire format, MD5/datatype/definition traits taken from the
  model's ROS 1 digests; nested messages, fixed and variable arrays, arrays of messages, strings and string
  arrays, `time`/`duration`, constants;
* the per-app glue mROS's library includes (`message_headers.h`: callback dispatch and MD5 lookup;
  `message_class_specialization.h`: each explicit instantiation exactly once; `msg_max_size.h`);
* the component API (`adaptor_components.h`): per component `register_()` (`register` is a C++ keyword),
  `registerPublishers()`/`registerSubscribers()`, `construct_P_Msg()`/`publish_P_Msg()` per published
  property, `get_P_value()` (a copy of the latest message taken under a semaphore) per subscribed one and
  `get_value()` when there is exactly one; `adaptor_hooks.h` (fill outgoing / handle incoming messages;
  weak no-op defaults); `td2a_config.h` (build-time settings);
* copied unchanged from `verbatim/` (`VERBATIM_FILES`): `include/td2a_wire.h` (wire-format helpers, `time` and
  `duration`), `include/td2a_support.h` (the latest-value slot, the robot namespace),
  `mros_config/os/target/os_asp/mros_os_config.h` (task priorities and stack sizes), `mros_os_config.c`
  (mROS's own task bodies and start-up) and `mros_config/mros_sys_config.c` (pools, user task start).

Layout: one publisher task (one node; advertises, then fills and publishes at a fixed rate) and one
subscriber task (one node; subscribes, then `ros::spin()`), as mROS binds nodes to tasks and `spin` blocks.

Robot namespace: topics written `/{{robotName}}/rest` become `/<TD2A_ROBOT_NAMESPACE>/rest`, a string-literal
macro (default `""`: the root namespace) set at build time, e.g. `make TD2A_ROBOT_NAMESPACE=rb1_base`. Its
length is checked at compile time (so every topic stays within mROS's 48 characters) and its characters at
start-up (the tasks then refuse to register, with a log line).

Limits and refusals are diagnostics (MROS9xx), never silent truncation: TD actions (mROS has no services;
error, or a warning each under `--partial`), node/topic/type-name lengths, table sizes, messages larger than
the largest pool block. Pool blocks are sized from bounded message sizes: unbounded strings and sequences
count with assumed capacities (options below); larger messages are refused at run time, with a log line.

Options (`GenOptions.extra`, all integers): `mros.string_capacity` (64 bytes), `mros.sequence_capacity`
(8 elements), `mros.max_pool_block` (65536 bytes), `mros.rate_hz` (publish rate, 10); the limits of the
user's mROS tree `mros.tcpros_header_max` (512) and `mros.xmlrpc_packet_max` (1024), and the longest ROS 1
peer node name `mros.peer_name_max` (64): every topic's TCPROS header and XML-RPC requests are computed
(`limits`) and refused when larger than the tree's buffers (MROS914-916).

Subscribed values are copied under a TOPPERS semaphore (`TD2A_LOCK_SEM`, created in `app.cfg`); the component
member functions live in `app.cpp`, so message copies are compiled once (footprint: bench/backend_mros.py).
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from td2adaptor.backends.mros import limits as proto
from td2adaptor.backends.mros import lint as mros_lint
from td2adaptor.backends.mros.types import (
    CPP_KEYWORDS,
    MACRO_LIKE,
    MAX_EMPTY_ELEMENTS,
    Capacities,
    MessageView,
    TypeViews,
    closure,
    comment,
    macro_like,
    unsupported_fields,
)
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.generation import textsafe as ts
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.generation.templating import render, verbatim
from td2adaptor.model import ArrayKind, Component, MessageDef, Model, Role, TopicEndpoint, TypeTable
from td2adaptor.model import genapi as api

TEMPLATES = Path(__file__).parent / "templates"
VERBATIM = Path(__file__).parent / "verbatim"
#: the files copied unchanged from `verbatim/`, by their path in the application directory
VERBATIM_FILES = (
    "include/td2a_support.h",
    "include/td2a_wire.h",
    "mros_config/mros_sys_config.c",
    "mros_config/os/target/os_asp/mros_os_config.c",
    "mros_config/os/target/os_asp/mros_os_config.h",
)


#: mROS v1.3 limits (mros_usr_config.h defaults and fixed buffers)
NODE_NAME_MAX = 19  # MROS_NODE_NAME_MAXLEN 20 incl. NUL
TOPIC_NAME_MAX = 48  # MROS_TOPIC_NAME_MAXLEN 50 incl. the added '/' and NUL
TYPE_NAME_MAX = 49  # MROS_TOPIC_TYPENAME_MAXLEN 50 incl. NUL
DEFAULT_TOPICS = 20
DEFAULT_PUB_CONNECTORS = 10
DEFAULT_SUB_CONNECTORS = 10
#: the default block classes of both pools (size, queue length); class 3 grows to fit the largest message
POOL_CLASSES = ((256, 16), (512, 8), (1024, 4))
POOL_ALIGN = 64
PREFIX = 4  # the length word mROS puts before each message in a pool block

OPTIONS: dict[str, tuple[int, int, int]] = {  # name → (default, min, max)
    "mros.string_capacity": (64, 0, 1 << 20),
    "mros.sequence_capacity": (8, 0, 1 << 16),
    "mros.max_pool_block": (65536, 1024, 1 << 24),
    "mros.rate_hz": (10, 1, 1000),
    # the limits of the user's mROS tree (stating one says the tree was changed to it) and what peers send
    "mros.tcpros_header_max": (proto.TCPROS_BUFFER, 64, 1 << 24),
    "mros.xmlrpc_packet_max": (proto.XMLRPC_BUFFER, 256, 1 << 24),
    "mros.peer_name_max": (64, 2, 1024),
}

#: the options that state the limits of the user's mROS tree
TREE_LIMITS = ("mros.tcpros_header_max", "mros.xmlrpc_packet_max")

#: every diagnostic this backend reports
CODES: dict[str, str] = meanings("MROS")  # texts in td2adaptor.diagnostics.catalogue

#: names the generated code uses in namespace `adaptor` / at file scope
_RESERVED = CPP_KEYWORDS | MACRO_LIKE | {"adaptor", "adaptor_hooks", "td2a", "ros", "std"}


@dataclass(frozen=True)
class PublisherView:
    prop: str
    msg: MessageView
    topic: str  # C++ expression of the topic name
    topic_text: str  # for comments and the README
    queue_size: int
    construct: str
    publish: str
    handle: str  # ros::Publisher member
    hook: str
    task_msg: str  # the publisher task's message object
    size_check: bool  # whether publish must check the size at run time
    comment: str


@dataclass(frozen=True)
class SubscriberView:
    prop: str
    msg: MessageView
    topic: str
    topic_text: str
    queue_size: int
    getter: str
    handle: str  # ros::Subscriber member
    latest: str  # td2a::Latest<> member
    callback: str
    hook: str
    comment: str


@dataclass(frozen=True)
class ComponentView:
    cls: str
    instance: str
    publishers: tuple[PublisherView, ...]
    subscribers: tuple[SubscriberView, ...]
    comment: str

    @property
    def single(self) -> SubscriberView | None:
        """The subscribed property `get_value()` returns, when there is exactly one."""
        return self.subscribers[0] if len(self.subscribers) == 1 else None


@dataclass(frozen=True)
class TaskView:
    id: str
    entry: str
    priority: str
    stack: str
    node: str  # macro holding the node name
    node_literal: str  # its default, a C string literal
    node_text: str
    kind: str  # "pub" or "sub"
    role: str


@dataclass(frozen=True)
class PoolView:
    prefix: str  # ROS_INNER_TOPIC_PUBLISHER / ROS_OUTER_TOPIC_PUBLISHER
    name: str  # ros_inner_topic_publisher_mempool
    config: str  # ros_inner_topic_publisher_config
    label: str
    classes: tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class TopicRow:
    prop: str
    topic: str
    type: str
    role: str
    size: int
    unbounded: bool  # with strings/sequences at the assumed capacities


@dataclass(frozen=True)
class SkippedAction:
    name: str
    ros_name: str
    type_name: str
    kind: str = "service"  # or "ROS action"


#: prefix of the per-field capacity options: `mros.capacity.<pkg>/msg/<Type>.<field>` = bytes or elements
FIELD_CAPACITY = "mros.capacity."

#: how large well-known unbounded fields of standard messages usually are (elements): a subscriber sized
#: below this cannot receive what real robots publish (a 0.5-degree laser scan has 720 ranges)
USUAL_SIZES: dict[tuple[str, str], int] = {
    ("sensor_msgs/msg/LaserScan", "ranges"): 720,
    ("sensor_msgs/msg/LaserScan", "intensities"): 720,
    ("sensor_msgs/msg/Image", "data"): 320 * 240,
    ("sensor_msgs/msg/CompressedImage", "data"): 16384,
    ("sensor_msgs/msg/PointCloud2", "data"): 16384,
    ("nav_msgs/msg/OccupancyGrid", "data"): 10000,
    ("nav_msgs/msg/Path", "poses"): 100,
    ("geometry_msgs/msg/PoseArray", "poses"): 100,
}


def _field_capacities(
    options: GenOptions, table: TypeTable, diags: Diagnostics
) -> tuple[tuple[tuple[str, str], int], ...]:
    """The per-field capacities asked for, checked against the message definitions."""
    out: dict[tuple[str, str], int] = {}
    for key, raw in options.extra:
        if not key.startswith(FIELD_CAPACITY):
            continue
        owner, _, name = key[len(FIELD_CAPACITY) :].rpartition(".")
        found = table.get(owner)
        field = next((f for f in found.fields if f.name == name), None) if isinstance(found, MessageDef) else None
        if field is None:
            diags.error(
                "MROS912",
                f"mros backend: option {key}: {owner or '?'} has no field {name!r}",
                hint="write mros.capacity.<pkg>/msg/<Type>.<field>, for a message the application uses",
            )
        elif not (field.type.base == "string" and not field.type.string_bound) and not (
            field.type.array is ArrayKind.SEQUENCE and not field.type.length
        ):
            diags.error("MROS912", f"mros backend: option {key}: {owner}.{name} is not an unbounded string or sequence")
        elif isinstance(raw, bool) or not isinstance(raw, int) or not 0 <= raw <= 1 << 24:
            diags.error("MROS912", f"mros backend: option {key} must be an integer in 0..{1 << 24}")
        else:
            out[(owner, name)] = raw
    return tuple(sorted(out.items()))


def _too_small(table: TypeTable, root: str, caps: Capacities) -> list[tuple[str, str, int, int]]:
    """Well-known fields reachable from `root` left at the global sequence capacity although that is below
    their usual size: (type, field, capacity, usual)."""
    out = []
    for name in closure(table, [root])[0]:
        for f in table.message(name).fields:
            usual = USUAL_SIZES.get((name, f.name))
            # a capacity set for the field itself is the user's decision; the global default is not
            if usual is not None and f.type.array is ArrayKind.SEQUENCE and not f.type.length:
                if caps.of(name, f.name) is None and caps.sequence < usual:
                    out.append((name, f.name, caps.sequence, usual))
    return out


def _options(options: GenOptions, diags: Diagnostics) -> dict[str, int]:
    values = {name: spec[0] for name, spec in OPTIONS.items()}
    for key, raw in options.extra:
        if not key.startswith("mros.") or key.startswith(FIELD_CAPACITY):
            continue
        spec = OPTIONS.get(key)
        if spec is None:
            diags.error("MROS912", f"mros backend: unknown option {key!r}", hint=f"known: {', '.join(OPTIONS)}")
            continue
        if isinstance(raw, bool) or not isinstance(raw, int) or not spec[1] <= raw <= spec[2]:
            diags.error("MROS912", f"mros backend: option {key} must be an integer in {spec[1]}..{spec[2]}")
            continue
        values[key] = raw
    return values


def _lower_first(name: str) -> str:
    return name[:1].lower() + name[1:]


def _topic(t: TopicEndpoint) -> tuple[str, str]:
    """(C++ expression, display text) of a topic name."""
    if t.ros_name.namespaced:
        return f"td2a::ns_topic({ts.c_str(t.ros_name.path)})", t.ros_name.binding_form()
    return ts.c_str(t.ros_name.path), t.ros_name.path


def _text(endpoint: TopicEndpoint) -> str:
    parts = [p for p in (endpoint.text.title, endpoint.text.description) if p]
    return comment(": ".join(parts)) if parts else ""


def _identifier_ok(name: str) -> bool:
    """A TD name usable inside C++ identifiers (the front end checks the same; this is defence in depth)."""
    return (
        bool(name)
        and name.isascii()
        and name[0].isalpha()
        and all(c.isalnum() or c == "_" for c in name)
        and "__" not in name
    )


def _check_limits(
    model: Model,
    topics: list[TopicEndpoint],
    diags: Diagnostics,
) -> int:
    """Report mROS name limits; the longest robot namespace every namespaced topic still fits."""
    ns_max = TOPIC_NAME_MAX
    for t in topics:
        length = 1 + len(t.ros_name.path) if t.ros_name.namespaced else len(t.ros_name.path)
        if length > TOPIC_NAME_MAX:
            diags.error(
                "MROS902",
                f"mros backend: topic {t.ros_name.binding_form()!r} of {t.name!r} has {length} characters "
                f"(without a robot namespace); mROS allows {TOPIC_NAME_MAX}",
                t.pointer,
            )
        elif t.ros_name.namespaced:
            ns_max = min(ns_max, TOPIC_NAME_MAX - 2 - len(t.ros_name.path))
        type_name = t.type_name.replace("/msg/", "/")
        if len(type_name) > TYPE_NAME_MAX:
            diags.error(
                "MROS904",
                f"mros backend: type name {type_name!r} of {t.name!r} has {len(type_name)} characters; mROS "
                f"allows {TYPE_NAME_MAX}",
                t.pointer,
            )
    if model.namespaced and ns_max < 1:
        diags.warning(
            "MROS903",
            "mros backend: a namespaced topic name leaves no room for a robot namespace within mROS's "
            f"{TOPIC_NAME_MAX} characters; only the root namespace fits",
        )
    return max(ns_max, 0)


def _pool(prefix: str, name: str, label: str, largest: int) -> PoolView:
    classes = list(POOL_CLASSES)
    if largest > classes[-1][0]:
        size = -(-largest // POOL_ALIGN) * POOL_ALIGN
        classes[-1] = (size, classes[-1][1])
    return PoolView(prefix, name, name.replace("_mempool", "_config"), label, tuple(classes))


def _master_ip(uri: str | None) -> str:
    """The master's IPv4 address when the TD's master URI names one (mROS takes no host names), else the
    address mROS's own examples use."""
    host = urlsplit(uri).hostname if uri else None
    try:
        return str(ipaddress.IPv4Address(host or ""))
    except ValueError:
        return "192.168.11.5"


def _render(template: str, **context: object) -> str:
    return render(TEMPLATES, template, **context)


def _skip_actions(model: Model, partial: bool, diags: Diagnostics) -> list[SkippedAction]:
    """Every TD action (mROS has neither services nor actions): an error each, or with --partial skipped, with
    one warning per kind that lists them (a configured partial target skips them on every run: the warnings
    would bury the rest). The README lists each skipped action."""
    skipped = []
    skips: dict[str, list[tuple[str, str]]] = {"MROS900": [], "MROS907": []}
    for component in model.components:
        for s in component.services:
            message = (
                f"mros backend: action {s.name!r} ({component.name}, service {s.ros_name.binding_form()} of type "
                f"{s.type_name}) cannot be generated: mROS 1 has no services"
            )
            if partial:
                skips["MROS900"].append((s.pointer, message))
            else:
                diags.error(
                    "MROS900",
                    message,
                    s.pointer,
                    hint="pass --partial to generate the topics and skip the actions, or use the rospy backend",
                )
            skipped.append(SkippedAction(s.name, s.ros_name.binding_form(), s.type_name))
        for a in component.actions:
            message = (
                f"mros backend: action {a.name!r} ({component.name}, ROS action {a.ros_name.binding_form()} of type "
                f"{a.type_name}) cannot be generated: mROS has no actions"
            )
            if partial:
                skips["MROS907"].append((a.pointer, message))
            else:
                diags.error(
                    "MROS907",
                    message,
                    a.pointer,
                    hint=(
                        "pass --partial to generate the topics and skip the actions, or use the rospy backend "
                        "(ROS 1 actions on actionlib; rclpy for ROS 2)"
                    ),
                )
            skipped.append(SkippedAction(a.name, a.ros_name.binding_form(), a.type_name, "ROS action"))
    for code, found in skips.items():
        if len(found) == 1:
            diags.warning(code, found[0][1] + "; skipped (--partial)", found[0][0])
        elif found:
            kind, lacks = ("ROS action", "mROS has no actions") if code == "MROS907" else ("service", "mROS 1 has none")
            names = ", ".join(s.name for s in skipped if s.kind == kind)
            diags.warning(
                code,
                f"mros backend: skipped {len(found)} actions bound to {kind}s (--partial; {lacks}): {names} "
                "(the package README lists them)",
                found[0][0],
            )
    return skipped


def _component(
    c: Component, views: TypeViews, block_max: int, diags: Diagnostics, taken: set[str]
) -> ComponentView | None:
    ok = True
    for name in [c.name, *(t.name for t in c.topics)]:
        if not _identifier_ok(name):
            diags.error("MROS922", f"mros backend: {name!r} is not usable in C++ names", hint="rename it in the TD")
            ok = False
    if not ok:
        return None
    cls = c.name
    if cls in _RESERVED or macro_like(cls) or cls in taken:
        cls = c.name + "Class"
        diags.warning(
            "MROS923", f"mros backend: component {c.name!r} is named {cls!r} in C++ ({c.name!r} is reserved there)"
        )
    instance = _lower_first(cls)
    if instance in _RESERVED or macro_like(instance) or instance in taken or instance == cls:
        instance += "Instance"
    members = [
        name
        for t in c.topics
        for name in (
            (api.CONSTRUCT_MESSAGE(t.name), api.PUBLISH(t.name), f"{t.name}_pub_")
            if t.role is Role.PUBLISHER
            else (api.GET(t.name), f"{t.name}_sub_", f"{t.name}_latest_", f"{t.name}_callback")
        )
    ]
    fixed = {"register_", "registerPublishers", "registerSubscribers", "get_value", "published_", "subscribed_"}
    if instance in taken or cls in taken or len(set(members)) != len(members) or fixed & set(members):
        diags.error("MROS923", f"mros backend: component {c.name!r}: generated C++ names collide")
        return None
    taken.update({cls, instance})
    pubs = []
    for t in c.publishers:
        msg = views.views[t.type_name]
        expr, text = _topic(t)
        pubs.append(
            PublisherView(
                prop=t.name,
                msg=msg,
                topic=expr,
                topic_text=comment(text),
                queue_size=t.qos.queue_size,
                construct=api.CONSTRUCT_MESSAGE(t.name),
                publish=api.PUBLISH(t.name),
                handle=f"{t.name}_pub_",
                hook=f"fill_{t.name}",
                task_msg=f"td2a_{c.name}_{t.name}_msg",
                size_check=not (msg.size.fixed and msg.size.max + PREFIX <= block_max),
                comment=_text(t),
            )
        )
        if t.qos.latch:
            diags.warning(
                "MROS906",
                f"mros backend: {t.name!r} asks for a latched publisher; mROS 1 cannot latch (the publisher task "
                "republishes at its rate while the fill hook returns true)",
                t.pointer,
            )
    subs = []
    for t in c.subscribers:
        msg = views.views[t.type_name]
        expr, text = _topic(t)
        subs.append(
            SubscriberView(
                prop=t.name,
                msg=msg,
                topic=expr,
                topic_text=comment(text),
                queue_size=t.qos.queue_size,
                getter=api.GET(t.name),
                handle=f"{t.name}_sub_",
                latest=f"{t.name}_latest_",
                callback=f"{t.name}_callback",
                hook=api.ON(t.name),
                comment=_text(t),
            )
        )
    return ComponentView(cls, instance, tuple(pubs), tuple(subs), comment(c.name))


def _sizes(topics: list[TopicEndpoint], table: TypeTable, ns_max: int, opts: dict[str, int]) -> list[proto.TopicSizes]:
    """The largest TCPROS header and XML-RPC request of every topic (see `limits`)."""
    callerid = "/" + "n" * (opts["mros.peer_name_max"] - 1)
    node = "n" * NODE_NAME_MAX  # the node names can be set at build time
    out = []
    for t in topics:
        path = t.ros_name.path.lstrip("/")
        if t.ros_name.namespaced and ns_max:
            path = "n" * ns_max + "/" + path
        topic = "/" + path
        type_name = t.type_name.replace("/msg/", "/")
        md5 = table.ros1_digest(t.type_name).md5
        definition, estimated = proto.full_definition(table, t.type_name)
        header = proto.publisher_reply if t.role is Role.SUBSCRIBER else proto.subscriber_request
        size = proto.header_size(header(topic, type_name, md5, definition, callerid))
        xmlrpc = max(proto.xmlrpc_register_size(node, topic, type_name), proto.xmlrpc_request_topic_size(node, topic))
        out.append(
            proto.TopicSizes(
                t.name,
                t.ros_name.binding_form(),
                t.role.value,
                size,
                len(definition.encode()),
                xmlrpc,
                tuple(n.replace("/msg/", "/") for n in estimated),
            )
        )
    return out


#: how much larger than counted without comments a header may be before a stated limit is trusted
_COMMENT_ALLOWANCE = 2


def _check_sizes(
    sizes: list[proto.TopicSizes],
    topics: list[TopicEndpoint],
    stated: set[str],
    opts: dict[str, int],
    ns_max: int,
    diags: Diagnostics,
) -> None:
    """Errors for protocol messages larger than mROS's buffers (upstream's, or the ones the user stated)."""
    tcpros_max, xmlrpc_max = opts["mros.tcpros_header_max"], opts["mros.xmlrpc_packet_max"]
    need_tcpros = max(s.tcpros for s in sizes)
    need_xmlrpc = max(s.xmlrpc for s in sizes)
    assumed = f"a peer node name of up to {opts['mros.peer_name_max']} characters (mros.peer_name_max)"
    if ns_max:
        assumed += f" and a robot namespace of up to {ns_max}"
    for s, t in zip(sizes, topics, strict=True):
        if s.tcpros > tcpros_max:
            sub = s.role == Role.SUBSCRIBER.value
            constant = "MROS_PACKET_MAXSIZE_RES_TCPROS" if sub else "MROS_PACKET_MAXSIZE_REQ_TCPROS"
            buffer = (
                f"the stated mros.tcpros_header_max of {tcpros_max} bytes"
                if "mros.tcpros_header_max" in stated
                else f"{constant} = {tcpros_max} bytes of upstream mROS"
            )
            peer = "a ROS 1 publisher answers with" if sub else "a rospy subscriber connects with"
            bound = "up to" if not s.estimated else "at least"
            unknown = (
                f"; {', '.join(s.estimated)} counted without comments (pass their .msg files with -I for exact sizes)"
                if s.estimated
                else ""
            )
            first = (
                "pass the .msg files of the types counted without comments with -I (Debian's ROS 1 packages: "
                "/usr/share/<package>) for the exact size, then "
                if s.estimated
                else ""
            )
            diags.error(
                "MROS914" if sub else "MROS915",
                f"mros backend: {s.prop!r} ({s.topic}): the TCPROS connection header {peer} has {bound} {s.tcpros} "
                f"bytes (its message definition alone {s.definition}; counted with {assumed}{unknown}); mROS reads "
                f"it without a bound check into a buffer of {buffer}",
                t.pointer,
                hint=f"{first}in your mROS tree, raise {constant} (and its REQ/RES twin) in {proto.PACKET_CONFIG} to "
                f"at least {need_tcpros}, then state it: --option mros.tcpros_header_max={need_tcpros}",
            )
        elif s.estimated and "mros.tcpros_header_max" in stated and s.tcpros * _COMMENT_ALLOWANCE > tcpros_max:
            diags.warning(
                "MROS917",
                f"mros backend: {s.prop!r} ({s.topic}): its TCPROS connection header has at least {s.tcpros} bytes, "
                f"within the stated mros.tcpros_header_max of {tcpros_max}, but {', '.join(s.estimated)} were "
                "counted without their comments, which a ROS 1 peer sends too: the real header may not fit "
                f"(no warning once the limit is {_COMMENT_ALLOWANCE}x the count)",
                t.pointer,
                hint="pass those types' .msg files with -I (Debian's ROS 1 packages: /usr/share/<package>) to check "
                "the exact size",
            )
        if s.xmlrpc > xmlrpc_max:
            diags.error(
                "MROS916",
                f"mros backend: {s.prop!r} ({s.topic}): mROS's XML-RPC request for it takes up to {s.xmlrpc} bytes, "
                f"more than its buffer of {xmlrpc_max}; the topic would never register",
                t.pointer,
                hint="in your mROS tree, raise every MROS_PACKET_MAXSIZE_*_REGISTER_* and *_REQUEST_TOPIC in "
                f"{proto.PACKET_CONFIG} to at least {need_xmlrpc}, then state it: "
                f"--option mros.xmlrpc_packet_max={need_xmlrpc}",
            )


@dataclass(frozen=True)
class Plan:
    """Everything the templates print, computed from the model; `empty` when there is no topic at all."""

    root: str  # the application directory in the tree, `<package>/`
    context: dict[str, Any]
    empty: bool = False


def plan(model: Model, options: GenOptions, diags: Diagnostics) -> Plan | None:
    """The application `generate` renders, or None when the model cannot become one (errors reported)."""
    opts = _options(options, diags)
    package = options.package_name or model.package_name
    root = f"{package}/"
    thing = comment(model.thing.title)
    skipped = _skip_actions(model, options.partial, diags)
    topics = [t for c in model.components for t in c.topics]
    base = {
        "package": package,
        "thing": thing,
        "skipped": skipped,
        "topics_count": len(topics),
    }
    if not topics:
        diags.warning(
            "MROS930",
            "mros backend: the TD binds no property to a topic; the mROS application would be empty "
            "(only README.md is generated)",
        )
        return Plan(root, base, empty=True)
    unusable = [(what, ep, why) for what, ep, why in model.unusable("ros1") if ep in topics]
    for what, ep, why in unusable:
        diags.error(
            "MROS931",
            f"mros backend: {what} cannot be generated: its type {ep.type_name} is for ROS 2 only ({why})",
            ep.pointer,
            hint="for ROS 1, give a definition ROS 1 can build with --interfaces",
        )
    if unusable:
        return None
    table = model.ros1
    roots = list(dict.fromkeys(t.type_name for t in topics))
    names, missing = closure(table, roots)
    if missing:
        diags.error(
            "MROS931",
            f"mros backend: ROS 1 message types not found: {', '.join(missing)}",
            hint="add their definitions with --interfaces",
        )
        return None
    bad = unsupported_fields(table, names)
    for type_name, field_name, field_type in bad:
        diags.error(
            "MROS932", f"mros backend: field {field_name!r} of {type_name} has type {field_type}, which ROS 1 lacks"
        )
    if bad:
        return None
    fields = _field_capacities(options, table, diags)
    if any(d.code == "MROS912" for d in diags):
        return None
    caps = Capacities(opts["mros.string_capacity"], opts["mros.sequence_capacity"], fields)
    views = TypeViews(table, roots, caps, diags)

    publishers = [t for t in topics if t.role is Role.PUBLISHER]
    subscribers = [t for t in topics if t.role is Role.SUBSCRIBER]
    largest_pub = max((views.size(t.type_name).max for t in publishers), default=0)
    largest_sub = max((views.size(t.type_name).max for t in subscribers), default=0)
    max_block = opts["mros.max_pool_block"]
    for t in topics:
        size = views.size(t.type_name)
        if size.max + PREFIX > max_block:
            diags.error(
                "MROS910",
                f"mros backend: {t.name!r} ({t.type_name}) can take {size.max} bytes on the wire"
                + (" (with the assumed string/sequence capacities)" if size.unbounded else "")
                + f"; with mROS's {PREFIX}-byte prefix it does not fit the largest pool block of {max_block} bytes",
                t.pointer,
                hint="raise the option mros.max_pool_block, or lower mros.string_capacity/mros.sequence_capacity",
            )
        elif t.role is Role.SUBSCRIBER and (small := _too_small(table, t.type_name, caps)):
            listed = ", ".join(f"{owner}.{name} ({cap} of usually {usual}+)" for owner, name, cap, usual in small)
            owner, name, _, usual = small[0]
            diags.warning(
                "MROS913",
                f"mros backend: {t.name!r} ({t.type_name}) is sized below what robots usually publish: {listed}; "
                "a larger message cannot be received",
                t.pointer,
                hint=f"--option {FIELD_CAPACITY}{owner}.{name}={usual} (or the project configuration's options)",
            )
        elif size.unbounded:
            diags.info(
                "MROS911",
                f"mros backend: {t.name!r} ({t.type_name}) has unbounded strings or sequences; its pool block is "
                f"sized for {size.max} bytes (strings of {caps.string} bytes, sequences of {caps.sequence} "
                "elements); larger ones are refused when publishing (with a log line) and cannot be received",
                t.pointer,
            )
    inner = _pool(
        "ROS_INNER_TOPIC_PUBLISHER",
        "ros_inner_topic_publisher_mempool",
        "data this application publishes",
        largest_pub + PREFIX,
    )
    outer = _pool(
        "ROS_OUTER_TOPIC_PUBLISHER",
        "ros_outer_topic_publisher_mempool",
        "data received from other nodes",
        largest_sub + PREFIX,
    )
    block_max = inner.classes[-1][0]

    base_name = package.removesuffix("_adaptor") or package
    tasks: list[TaskView] = []
    node_names: dict[str, str] = {}
    for kind, role, wanted in (("pub", "publisher", publishers), ("sub", "subscriber", subscribers)):
        if not wanted:
            continue
        number = len(tasks) + 1
        node = f"{base_name}_{kind}"
        if len(node) > NODE_NAME_MAX:
            diags.warning(
                "MROS901",
                f"mros backend: the node name {node!r} of the {role} task would have {len(node)} characters; "
                f"mROS allows {NODE_NAME_MAX}, so it defaults to 'td2a_{kind}'",
                hint=f"set TD2A_{kind.upper()}_NODE_NAME when building (unique per board), or choose a shorter "
                "--package-name (node names are <package without _adaptor>_pub/_sub)",
            )
            node = f"td2a_{kind}"
        node_names[role] = node
        tasks.append(
            TaskView(
                id=f"TD2A_{kind.upper()}_TASK",
                entry=f"td2a_{kind}_task",
                priority=f"MROS_USR_TASK{number}_PRI",
                stack=f"MROS_USR{number}_STACK_SIZE",
                node=f"TD2A_{kind.upper()}_NODE_NAME",
                node_literal=ts.c_str(node),
                node_text=comment(node),
                kind=kind,
                role=f"{role} task",
            )
        )
    ns_max = _check_limits(model, topics, diags)
    sizes = _sizes(topics, table, ns_max, opts)
    _check_sizes(sizes, topics, {key for key, _ in options.extra}, opts, ns_max, diags)
    n_topics = len({t.ros_name.binding_form() for t in topics})
    limits = {
        "topics": max(DEFAULT_TOPICS, n_topics),
        "pub": max(DEFAULT_PUB_CONNECTORS, len(publishers)),
        "sub": max(DEFAULT_SUB_CONNECTORS, len(subscribers)),
    }
    for what, count, default, macro in (
        ("topics", n_topics, DEFAULT_TOPICS, "MROS_TOPIC_MAX_NUM"),
        ("published properties", len(publishers), DEFAULT_PUB_CONNECTORS, "MROS_PUB_TOPIC_CONNECTOR_MAX_NUM"),
        ("subscribed properties", len(subscribers), DEFAULT_SUB_CONNECTORS, "MROS_SUB_TOPIC_CONNECTOR_MAX_NUM"),
    ):
        if count > default:
            diags.warning(
                "MROS905",
                f"mros backend: {count} {what} exceed mROS's default table size of {default}; {macro} is raised to "
                f"{count} in mros_config/mros_usr_config.h",
            )

    taken: set[str] = set()
    components = []
    for c in model.components:
        if not c.topics:
            continue
        view = _component(c, views, block_max, diags, taken)
        if view is not None:
            components.append(view)
    messages = [views.views[n] for n in views.order]
    sub_types = [views.views[n] for n in dict.fromkeys(t.type_name for t in subscribers)]
    pub_types = [views.views[n] for n in dict.fromkeys(t.type_name for t in publishers)]
    topic_types = [views.views[n] for n in roots]
    context = {
        **base,
        "components": components,
        "publishers": [p for c in components for p in c.publishers],
        "subscribers": [s for c in components for s in c.subscribers],
        "tasks": tasks,
        "messages": messages,
        "topic_types": topic_types,
        "sub_types": sub_types,
        "pub_types": pub_types,
        "pools": [inner, outer],
        "block_max": block_max,
        "pub_msg_max": largest_pub,
        "limits": limits,
        "node_names": node_names,
        "node_name_max": NODE_NAME_MAX,
        "ns_max": ns_max,
        "namespaced": model.namespaced,
        "rate_hz": opts["mros.rate_hz"],
        "caps": caps,
        "max_empty": MAX_EMPTY_ELEMENTS,
        "max_block": max_block,
        "master_uri": comment(model.thing.master_uri or ""),
        "master_ip": ts.c_str(_master_ip(model.thing.master_uri)),
        "topic_name_max": TOPIC_NAME_MAX,
        "sizes": sizes,
        "tcpros_max": opts["mros.tcpros_header_max"],
        "xmlrpc_max": opts["mros.xmlrpc_packet_max"],
        "peer_name_max": opts["mros.peer_name_max"],
        "need_tcpros": max(s.tcpros for s in sizes),
        "need_xmlrpc": max(s.xmlrpc for s in sizes),
        "stated_limits": sorted(k for k, _ in options.extra if k in TREE_LIMITS),
        "packet_config": proto.PACKET_CONFIG,
        "topic_rows": [
            TopicRow(
                t.name,
                comment(_topic(t)[1]),
                t.type_name.replace("/msg/", "/"),
                t.role.value,
                views.size(t.type_name).max,
                views.size(t.type_name).unbounded,
            )
            for t in topics
        ],
    }
    return Plan(root, context)


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    """The mROS application directory for `model` (see the module docstring)."""
    tree = GeneratedTree()
    made = plan(model, options, diags)
    if made is None:
        return tree
    root, context = made.root, made.context
    if made.empty:
        tree.add(root + "README.md", _render("README.empty.md.j2", **context))
        return tree
    tree.add(root + "README.md", _render("README.md.j2", **context))
    tree.add(root + "app.cpp", _render("app.cpp.j2", **context))
    tree.add(root + "app.h", _render("app.h.j2", **context))
    tree.add(root + "app.cfg", _render("app.cfg.j2", **context))
    tree.add(root + "Makefile", _render("Makefile.j2", **context))
    tree.add(root + "mros_config/mros_sys_config.h", _render("mros_config/mros_sys_config.h.j2", **context))
    tree.add(root + "mros_config/mros_usr_config.h", _render("mros_config/mros_usr_config.h.j2", **context))
    tree.add(root + "mros_config/mros_usr_config.c", _render("mros_config/mros_usr_config.c.j2", **context))
    for rel in VERBATIM_FILES:
        tree.add(root + rel, verbatim(VERBATIM, rel))
    inc = root + "include/"
    for name in (
        "message_headers.h",
        "message_class_specialization.h",
        "msg_max_size.h",
        "td2a_config.h",
        "adaptor_components.h",
        "adaptor_hooks.h",
    ):
        tree.add(inc + name, _render(f"include/{name}.j2", **context))
    for msg in context["messages"]:
        tree.add(inc + msg.header, _render("include/message.h.j2", m=msg, **context))
    files = {rel: tree.files[root + rel].decode("utf-8") for rel in mros_lint.CHECKED}
    inconsistent = mros_lint.problems(files)
    if inconsistent:  # a bug of this backend, never of the input
        raise AssertionError(f"mros backend produced an inconsistent task configuration: {inconsistent}")
    return tree
