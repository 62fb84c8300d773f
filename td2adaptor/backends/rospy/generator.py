"""The rospy backend: a catkin package of typed component classes for ROS 1, with type stubs for its messages.

Everything a template prints is computed here (the view model); templates only loop and print. The run-time
modules and the rospy/genpy stubs are copied unchanged (`verbatim/`, and `common.py` and `errors.py` shared
with the rclpy backend in `backends/_python/verbatim/`). Every TD string reaches the output through
`textsafe`. Output: `<package>/` with package.xml, CMakeLists.txt, setup.py, README.md, mypy.ini, ruff.toml,
`src/<package>/`, `scripts/edge_node` (rosrun), `launch/edge_node.launch` (roslaunch) and `stubs/`. ROS actions
become actionlib clients (`_actions.py`, copied only into packages that have actions: they need actionlib).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from td2adaptor.backends import _python as py
from td2adaptor.backends._python import LINE as LINE  # the generated line length, for tests and tools
from td2adaptor.backends._python import StubClass, StubField, StubModule, import_block
from td2adaptor.backends.rospy.types import (
    FieldView,
    class_location,
    constant_annotation,
    field_problem,
    field_view,
    stub_annotation,
)
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation import textsafe as ts
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.generation.templating import render, verbatim
from td2adaptor.model import (
    ActionDef,
    ActionEndpoint,
    Component,
    Failure,
    MessageDef,
    Model,
    ProcedureRole,
    RosName,
    ServiceDef,
    ServiceEndpoint,
    Text,
    TopicEndpoint,
    TypeTable,
)
from td2adaptor.model import genapi as api
from td2adaptor.support.providers import providers

TEMPLATES = Path(__file__).parent / "templates"


VERBATIM = Path(__file__).parent / "verbatim"
#: copied unchanged: the parts of rospy and genpy the package uses, typed
_FIXED_STUBS = (
    "genpy/__init__.pyi",
    "rosgraph/__init__.pyi",
    "rospy/__init__.pyi",
    "rospy/core.pyi",
    "rospy/exceptions.pyi",
)
#: copied unchanged into packages with actions: the parts of actionlib they use, typed
_ACTION_STUBS = ("actionlib/__init__.pyi",)

#: names the generated components module must not give to message classes or parameters: what the runtime
#: modules define, what the template uses besides them, keywords and builtins
_RESERVED = py.reserved_names(
    [verbatim(VERBATIM, "_runtime.py"), verbatim(VERBATIM, "_actions.py"), *(py.shared_source(n) for n in py.SHARED)],
    ["annotations", "Any", "Callable", "Mapping", "Sequence", "genpy", "self", "item", "request", "response"]
    + ["mission_id", "timeout", "goal"],
)

# ---------------------------------------------------------------------------------------------------------
# docstrings


def docstring(td_parts: Iterable[str | None], fixed: Iterable[str], indent: str) -> str:
    """A docstring: TD text first (wrapped, escaped), then our own paragraphs, so it never ends in TD text."""
    return py.docstring([*td_parts, *fixed], indent)


def _td_text(text: Text) -> list[str | None]:
    if text.title and text.description:
        return [f"{text.title}: {text.description}"]
    return [text.title or text.description]


# ---------------------------------------------------------------------------------------------------------
# view model


@dataclass(frozen=True)
class ServiceView:
    name: str
    attr: str
    ros_name: list[str]  # argument lines of the name expression (see `_name_expr`)
    display_name: str
    srv_class: str
    req_class: str
    resp_class: str
    params: list[FieldView]
    construct_doc: str
    call_doc: str
    returns: str
    fail_condition: str | None
    fail_message: str | None
    mission_expr: str | None  # run: where the response holds the mission id
    mission_attr: str | None  # run: where the last id is kept; query/cancel: where to read it
    mission_target: str | None  # query/cancel: the request field taking the id


@dataclass(frozen=True)
class SubscriberView:
    name: str
    attr: str
    ros_name: list[str]
    msg_class: str
    queue_size: int
    get_doc: str
    on_doc: str
    serialized_doc: str = ""


@dataclass(frozen=True)
class PublisherView:
    name: str
    attr: str
    ros_name: list[str]
    msg_class: str
    queue_size: int
    latch: str
    params: list[FieldView]
    construct_doc: str
    publish_doc: str


@dataclass(frozen=True)
class ActionView:
    name: str
    attr: str
    ros_name: list[str]
    action_class: str  # genaction's NameAction, what actionlib.ActionClient wants
    goal_class: str
    result_class: str
    feedback_class: str
    params: list[FieldView]
    construct_doc: str
    send_doc: str
    start_doc: str
    rejoin_doc: str


@dataclass(frozen=True)
class ComponentView:
    name: str
    doc: str
    init_doc: str
    services: list[ServiceView]
    subscribers: list[SubscriberView]
    publishers: list[PublisherView]
    single: SubscriberView | None
    mission_attrs: list[str]
    actions: list[ActionView] = field(default_factory=list)


@dataclass
class _Imports:
    """Message and service classes the components module imports, each under a name unique in the module."""

    taken: set[str]
    local: dict[str, str] = field(default_factory=dict)  # canonical type (or pkg/srv/Name) → local name
    modules: dict[str, list[tuple[str, str]]] = field(default_factory=dict)  # module → (class, alias)

    def use(self, canonical: str) -> str:
        if canonical in self.local:
            return self.local[canonical]
        module, cls = class_location(canonical)
        name = cls
        if name in self.taken:
            name = f"{module.split('.')[0]}_{cls}"
            while name in self.taken:
                name += "_"
        self.taken.add(name)
        self.local[canonical] = name
        self.modules.setdefault(module, []).append((cls, name))
        return name

    def pairs(self) -> list[tuple[str, str]]:
        """(module, `Class` or `Class as alias`) of every class used, for `import_block`."""
        return [
            (module, cls if cls == alias else f"{cls} as {alias}")
            for module, classes in self.modules.items()
            for cls, alias in classes
        ]


def module_imports(views: list[ComponentView], imports: _Imports) -> list[str]:
    """The import block of components.py: only what the generated code uses, grouped and sorted like isort."""
    text: list[str] = []
    for v in views:
        for s in v.services:
            text += [p.annotation + " " + p.value for p in s.params] + s.ros_name
            text += [s.returns, s.fail_condition or "", s.fail_message or "", s.mission_expr or ""]
        for sub in v.subscribers:
            text += [*sub.ros_name, "Callable TopicSubscriber"]
        for pub in v.publishers:
            text += [p.annotation + " " + p.value for p in pub.params] + pub.ros_name + ["TopicPublisher"]
        for act in v.actions:
            text += [p.annotation + " " + p.value for p in act.params] + act.ros_name
            text += ["ActionGoalClient Callable GoalHandle GoalOutcome"]
        if v.services:
            text.append("ServiceClient")
        if v.services or v.actions:
            text.append("master_state")
        if v.mission_attrs:
            text.append("LAST_MISSION")
    blob = " ".join(text)
    if any(s.fail_condition for v in views for s in v.services):
        blob += " CallFailed"

    def used(*names: str) -> list[str]:
        return [n for n in names if re.search(rf"\b{n}\b", blob)]

    members = [("collections.abc", n) for n in used("Callable", "Mapping", "Sequence")]
    members += [("typing", n) for n in used("Any")] + imports.pairs()
    runtime = ["DEFAULT_TIMEOUT", "DEFAULT_WAIT_TIMEOUT", "check_robot_name", "check_timeout", "require_node"] + used(
        "ERROR_WITHOUT_MESSAGE",
        "FAILURE_WITHOUT_MESSAGE",
        "LAST_MISSION",
        "ServiceClient",
        "Started",
        "check_float32",
        "check_float32s",
        "check_float64",
        "check_float64s",
        "TopicPublisher",
        "TopicSubscriber",
        "in_namespace",
        "master_state",
        "to_duration",
        "to_list",
        "to_msg",
        "to_msgs",
        "to_time",
    )
    members += [(".common" if n in py.common_names() else "._runtime", n) for n in runtime]
    members += [("._actions", n) for n in used("ActionGoalClient", "GoalHandle")]
    members += [(".goals", n) for n in used("GoalOutcome")]
    members += [(".errors", n) for n in used("CallFailed")]
    return import_block(members, used("genpy"))


def _name_expr(name: RosName) -> list[str]:
    """The arguments that build a graph name at run time: a literal, or the namespaced path and the robot name."""
    if name.namespaced:
        return [f"in_namespace({ts.py_str(name.path)}, self.robot_name)"]
    return [ts.py_str(name.path)]


def _params(msg: MessageDef, imports: _Imports, diags: Diagnostics, where: str) -> list[FieldView]:
    out = []
    for f in msg.fields:
        problem = field_problem(f)
        if problem:
            diags.error("GEN840", f"rospy backend: {msg.name}: {problem}", where)
            continue
        if f.type.is_message:
            imports.use(f.type.base)
        param = py.param_name(f.name, _RESERVED | imports.taken)
        out.append(field_view(f, param, imports.local))
    return out


#: the condition and the message of a CallFailed, by how the response says the robot failed (`Failure`)
_FAILURE: dict[Failure, tuple[str | None, str | None]] = {
    Failure.NONE: (None, None),
    Failure.RESULT: ('response.result.result == "error"', "response.result.message or ERROR_WITHOUT_MESSAGE"),
    Failure.SUCCESS: ("not response.success", "response.message or FAILURE_WITHOUT_MESSAGE"),
    Failure.SUCCESS_ONLY: ("not response.success", "FAILURE_WITHOUT_MESSAGE"),
}


def _service_view(
    comp: Component, svc: ServiceEndpoint, types: TypeTable, imports: _Imports, diags: Diagnostics
) -> ServiceView:
    sdef: ServiceDef = types.service(svc.type_name)
    srv_class = imports.use(svc.type_name)
    req_class = imports.use(sdef.request.name)
    resp_class = imports.use(sdef.response.name)
    params = _params(sdef.request, imports, diags, svc.pointer)
    fail_condition, fail_message = _FAILURE[svc.failure]
    proc = comp.procedure_of(svc.name)
    display = svc.ros_name.binding_form()
    returns = resp_class
    mission_expr = mission_attr = mission_target = None
    notes = []
    if proc is not None and svc.procedure_role is ProcedureRole.RUN and proc.mission_id:
        mission_expr = "response." + ".".join(proc.mission_id)
        mission_attr = f"_mission_{svc.name}"
        returns = f"Started[{resp_class}]"
        notes.append(
            f"Returns Started(mission_id, response): the mission id is the response's "
            f"{'.'.join(proc.mission_id)}; query and cancel use it by default."
        )
    elif proc is not None and svc.procedure_role in (ProcedureRole.QUERY, ProcedureRole.CANCEL):
        slot = proc.slot(svc.procedure_role.value)
        if slot:
            mission_target = "request." + ".".join(slot)
            mission_attr = f"_mission_{proc.run}"
            notes.append(
                f"Without a request, asks about mission_id: by default the mission this object last started "
                f"with {api.CALL(proc.run)}, or -1 (the robot's last procedure) when it has started none. Pass "
                f"mission_id explicitly when several callers share the robot."
            )
    raises = "Raises ServiceUnavailable (not reachable), CallTimeout (no answer within timeout, default self.timeout)"
    if fail_condition:
        raises += " or CallFailed (the robot reports failure; .message is its explanation)."
    else:
        raises += " or CallFailed (the call failed on the robot)."
    call_doc = docstring(
        _td_text(svc.text), [f"Call {display} ({sdef.name.replace('/srv/', '/')}).", *notes, raises], " " * 8
    )
    construct_doc = docstring(
        [f"The request of {svc.name}."],
        ["Keyword arguments are the request's fields; nested messages may also be mappings of their fields."],
        " " * 8,
    )
    return ServiceView(
        name=svc.name,
        attr=f"_svc_{svc.name}",
        ros_name=_name_expr(svc.ros_name),
        display_name=display,
        srv_class=srv_class,
        req_class=req_class,
        resp_class=resp_class,
        params=params,
        construct_doc=construct_doc,
        call_doc=call_doc,
        returns=returns,
        fail_condition=fail_condition,
        fail_message=fail_message,
        mission_expr=mission_expr,
        mission_attr=mission_attr,
        mission_target=mission_target,
    )


def _subscriber_view(topic: TopicEndpoint, imports: _Imports) -> SubscriberView:
    msg_class = imports.use(topic.type_name)
    display = topic.ros_name.binding_form()
    ros_type = topic.type_name.replace("/msg/", "/")
    get_doc = docstring(
        _td_text(topic.text),
        [
            f"The latest {ros_type} message on {display}, waiting at most timeout seconds (by default "
            "self.timeout) for the first one. Raises NoMessage when none arrives in time."
        ],
        " " * 8,
    )
    on_doc = docstring(
        [f"Call callback with every {ros_type} message on {display}."],
        ["Callbacks run in rospy's receive thread; returns a function that removes the callback."],
        " " * 8,
    )
    serialized_doc = docstring(
        [f"Call callback with every {ros_type} message on {display}, serialized (the ROS 1 wire format)."],
        [
            "The twin of the rclpy package's method: rospy hands over messages, so each is serialized again "
            f"({msg_class}().deserialize(data) gives it back). Returns a function that removes the callback."
        ],
        " " * 8,
    )
    return SubscriberView(
        name=topic.name,
        attr=f"_sub_{topic.name}",
        ros_name=_name_expr(topic.ros_name),
        msg_class=msg_class,
        queue_size=max(1, topic.qos.queue_size),
        get_doc=get_doc,
        on_doc=on_doc,
        serialized_doc=serialized_doc,
    )


def _publisher_view(topic: TopicEndpoint, types: TypeTable, imports: _Imports, diags: Diagnostics) -> PublisherView:
    msg_class = imports.use(topic.type_name)
    params = _params(types.message(topic.type_name), imports, diags, topic.pointer)
    display = topic.ros_name.binding_form()
    ros_type = topic.type_name.replace("/msg/", "/")
    latch = " (latched: late subscribers get the last message)" if topic.qos.latch else ""
    publish_doc = docstring(_td_text(topic.text), [f"Publish msg on {display} ({ros_type}){latch}."], " " * 8)
    construct_doc = docstring(
        [f"A {ros_type} message for {topic.name}."],
        ["Keyword arguments are the message's fields; nested messages may also be mappings of their fields."],
        " " * 8,
    )
    return PublisherView(
        name=topic.name,
        attr=f"_pub_{topic.name}",
        ros_name=_name_expr(topic.ros_name),
        msg_class=msg_class,
        queue_size=max(1, topic.qos.queue_size),
        latch="True" if topic.qos.latch else "False",
        params=params,
        construct_doc=construct_doc,
        publish_doc=publish_doc,
    )


def _action_view(action: ActionEndpoint, types: TypeTable, imports: _Imports, diags: Diagnostics) -> ActionView:
    adef: ActionDef = types.action(action.type_name)
    action_class = imports.use(action.type_name)
    goal_class = imports.use(adef.goal.name)
    result_class = imports.use(adef.result.name)
    feedback_class = imports.use(adef.feedback.name)
    params = _params(adef.goal, imports, diags, action.pointer)
    display = action.ros_name.binding_form()
    ros_type = action.type_name.replace("/action/", "/")
    send_doc = docstring(
        _td_text(action.text),
        [
            f"Send a goal to ROS action {display} ({ros_type}, actionlib: {display}/goal, cancel, status, feedback, "
            "result).",
            f"goal=None sends {api.CONSTRUCT_GOAL(action.name)}() (all fields zero). Returns the goal's GoalHandle: "
            "goal_id, status, on_feedback(callback), feedback(timeout=...) to iterate over the feedback until the "
            "goal ends, result(timeout=...) and cancel(timeout=...). Its waits default to timeout (default: "
            "self.timeout).",
            "Raises ServiceUnavailable when no action server is connected within wait_timeout, GoalRejected when "
            "the server rejects the goal, CallTimeout when it does not take the goal up within timeout (the goal "
            "is then cancelled); result() raises GoalAborted or GoalCanceled when the goal does not succeed.",
        ],
        " " * 8,
    )
    start_doc = docstring(
        [],
        [
            f"{api.SEND(action.name)} without waiting: returns the goal's GoalHandle at once (its goal_id is known) "
            "and "
            "tells what happens to the callbacks: on_accepted() once the server reported the goal, "
            "on_status(status) at each change of status while it runs, on_feedback(message) with each feedback "
            "message, in order, then exactly one on_done(outcome), a GoalOutcome: status succeeded, canceled, "
            "aborted, rejected or lost (no server within wait_timeout, no report within timeout, the server went "
            "away), result, error. on_done waits feedback_grace seconds (default: _actions.FEEDBACK_GRACE) after "
            "the result for feedback still on its way.",
            "The callbacks run in rospy's receive threads or in the adaptor's goals thread, never two at once for "
            "one goal: they must return quickly (hand the event on to your own loop). The handle's feedback(), "
            "result() and cancel() read the same record; request_cancel(on_done) cancels without waiting. Raises "
            "only InvalidMessage (a goal of another type), ValueError (a bad timeout) and NotInitialized.",
        ],
        " " * 8,
    )
    rejoin_doc = docstring(
        [],
        [
            f"Follow the goal goal_id that the server took from another client (this process before a restart, "
            f"another process), as {api.START(action.name)} follows its own: its GoalHandle at once, on_accepted() "
            "once the server reports the goal, then its status, the feedback from now on and exactly one "
            "on_done(outcome): the result the server publishes; for a goal that ended before it was followed, the "
            "end its status tells, without a result (actionlib sends a result once); lost when the server does "
            "not list the goal (it ended a while ago, or never its). Raises only ValueError (an empty id, a bad "
            "timeout) and NotInitialized.",
        ],
        " " * 8,
    )
    construct_doc = docstring(
        [f"The goal of {action.name}."],
        ["Keyword arguments are the goal's fields; nested messages may also be mappings of their fields."],
        " " * 8,
    )
    return ActionView(
        name=action.name,
        attr=f"_act_{action.name}",
        ros_name=_name_expr(action.ros_name),
        action_class=action_class,
        goal_class=goal_class,
        result_class=result_class,
        feedback_class=feedback_class,
        params=params,
        construct_doc=construct_doc,
        send_doc=send_doc,
        start_doc=start_doc,
        rejoin_doc=rejoin_doc,
    )


def component_views(model: Model, imports: _Imports, diags: Diagnostics) -> list[ComponentView]:
    types = model.ros1
    views = []
    for comp in model.components:
        services = [_service_view(comp, s, types, imports, diags) for s in comp.services]
        subscribers = [_subscriber_view(t, imports) for t in comp.subscribers]
        publishers = [_publisher_view(t, types, imports, diags) for t in comp.publishers]
        actions = [_action_view(a, types, imports, diags) for a in comp.actions]
        members = [s.name for s in comp.services] + [a.name for a in comp.actions] + [t.name for t in comp.topics]
        doc = docstring(
            [],
            [
                f"The robot's {comp.name}: {', '.join(members) or 'nothing'}.",
                "Call rospy.init_node() once in the process first (rospy has one node per process, and it is "
                "the caller's), then register() (or just use the methods: they register what they need).",
            ],
            " " * 4,
        )
        init_doc = docstring(
            [],
            [
                "Bind the component to one robot.",
                "robot_name is the robot's namespace (e.g. rb1_base_a); it replaces {{robotName}} in the names "
                "below and is checked here (InvalidRobotName). timeout bounds each service call and each wait for "
                "a first message by default; wait_timeout bounds waiting for a service to appear. Both in seconds.",
            ],
            " " * 8,
        )
        mission_attrs = sorted({s.mission_attr for s in services if s.mission_attr and s.mission_expr})
        view = ComponentView(
            name=comp.name,
            doc=doc,
            init_doc=init_doc,
            services=services,
            subscribers=subscribers,
            publishers=publishers,
            single=subscribers[0] if len(subscribers) == 1 else None,
            mission_attrs=mission_attrs,
            actions=actions,
        )
        names = [[x.name for x in group] for group in (services, actions, subscribers, publishers)]
        clashes = api.clashes(*names)
        for member, owner, other in clashes:
            diags.error(
                "GEN841",
                f"rospy backend: {comp.name}: method {member} of {owner} clashes with {other}",
                hint="rename one of the affordances",
            )
        views.append(view)
    return views


# ---------------------------------------------------------------------------------------------------------
# type stubs


def _stub_class(msg: MessageDef, module: str, diags: Diagnostics) -> tuple[StubClass, set[str]]:
    """A stub class; other modules it refers to."""
    used: set[str] = set()
    ref: dict[str, str] = {}
    for f in msg.fields:
        if f.type.is_message:
            other, cls = class_location(f.type.base)
            ref[f.type.base] = cls if other == module else f"{other}.{cls}"
            if other != module:
                used.add(other)
    fields = []
    for f in msg.fields:
        problem = field_problem(f)
        if problem:
            diags.error("GEN840", f"rospy backend: {msg.name}: {problem}")
            continue
        annotation = stub_annotation(f.type, ref)
        fields.append(StubField(f.name, annotation, annotation))
    constants = [
        f"{c.name}: ClassVar[{constant_annotation(c.type)}]"
        for c in msg.constants
        if c.name.isidentifier() and c.name.isascii()
    ]
    return StubClass(class_location(msg.name)[1], constants, fields), used


def stub_modules(types: TypeTable, diags: Diagnostics) -> list[StubModule]:
    by_module: dict[str, list[MessageDef]] = {}
    services: dict[str, list[ServiceDef]] = {}
    for msg in types.messages:
        by_module.setdefault(class_location(msg.name)[0], []).append(msg)
    for srv in types.services:
        module = class_location(srv.name)[0]
        services.setdefault(module, []).append(srv)
        by_module.setdefault(module, []).extend([srv.request, srv.response])
    actions: dict[str, list[ActionDef]] = {}
    for act in types.actions:
        module = class_location(act.name)[0]
        actions.setdefault(module, []).append(act)
        listed = {m.name for m in by_module.get(module, [])}  # a genaction message may have brought them in
        by_module.setdefault(module, []).extend(m for m in (act.goal, act.result, act.feedback) if m.name not in listed)
    out = []
    for module in sorted(by_module):
        classes = []
        used: set[str] = set()
        for msg in sorted(by_module[module], key=lambda m: class_location(m.name)[1]):
            cls, refs = _stub_class(msg, module, diags)
            classes.append(cls)
            used |= refs
        classes += [
            StubClass(
                class_location(s.name)[1], [], [], class_location(s.request.name)[1], class_location(s.response.name)[1]
            )
            for s in sorted(services.get(module, []), key=lambda s: s.name)
        ]
        # genaction's NameAction: only passed to actionlib.ActionClient, which reads its parts itself
        classes += [StubClass(class_location(a.name)[1], [], []) for a in actions.get(module, [])]
        annotations = " ".join(a for c in classes for a in (*(f.annotation for f in c.fields), *c.constants))
        members = [("collections.abc", "Sequence")] if "Sequence[" in annotations else []
        if "ClassVar[" in annotations or module in services:
            members.append(("typing", "ClassVar"))
        imports = import_block(members, {"genpy"} | used)
        header = f"# Type stubs of {module} (genpy), generated by td2adaptor: only the types the adaptor uses."
        out.append(StubModule(module.replace(".", "/") + "/__init__.pyi", header, imports, classes))
    return out


# ---------------------------------------------------------------------------------------------------------
# package metadata


def _version(raw: str | None) -> str:
    """package.xml wants X.Y.Z; a TD's version.instance often is one."""
    return raw if raw and re.fullmatch(r"\d+\.\d+\.\d+", raw) else "0.0.0"


def interface_packages(types: TypeTable) -> list[str]:
    names = {m.package for m in types.messages} | {s.package for s in types.services}
    names |= {a.name.split("/")[0] for a in types.actions}
    if types.actions:
        names.add("actionlib_msgs")  # the goal ids and statuses of the action messages
    return sorted(names)


def _render(template: str, **context: object) -> str:
    return render(TEMPLATES, template, **context)


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    """The catkin package for `model` (see the module docstring)."""
    tree = GeneratedTree()
    types = model.ros1
    unusable = model.unusable("ros1")
    for what, ep, why in unusable:
        diags.error(
            "GEN842",
            f"rospy backend: {what} cannot be generated: its type {ep.type_name} is for ROS 2 only ({why})",
            ep.pointer,
            hint="the rclpy backend generates it for ROS 2; for ROS 1, give a definition ROS 1 can build with -I",
        )
    if unusable:
        return tree
    if types.missing:
        diags.error(
            "GEN842",
            f"rospy backend: ROS 1 types not found: {', '.join(types.missing)}",
            hint="add their definitions with --interfaces, or pick another backend",
        )
        return tree
    pkg = options.package_name or model.package_name
    taken = set(_RESERVED) | {c.name for c in model.components}
    imports = _Imports(taken=taken)
    views = component_views(model, imports, diags)
    stubs = stub_modules(types, diags)
    packages = interface_packages(types)
    standard = set(model.standard_packages) | ({"actionlib_msgs"} if types.actions else set())
    thing = model.thing
    title = ts.py_comment(thing.title)
    description = thing.description or thing.title
    context: dict[str, object] = {
        "package": pkg,
        "components": views,
        "imports": module_imports(views, imports),
        "timeout": py.constant("DEFAULT_TIMEOUT"),
        "wait_timeout": py.constant("DEFAULT_WAIT_TIMEOUT"),
        "module_doc": docstring(
            [thing.title, thing.description],
            ["Component classes generated by td2adaptor from the Thing Description; regenerate instead of editing."],
            "",
        ),
        "init_doc": docstring([thing.title], [f"ROS 1 (rospy) adaptor package {pkg}, generated by td2adaptor."], ""),
        "errors": sorted(py.error_classes()),
        "exports": sorted(
            [v.name for v in views]
            + list(py.error_classes())
            + ["LAST_MISSION", "Started"]
            + (["CancelOutcome", "GoalHandle", "GoalOutcome"] if types.actions else [])
        ),
        "interface_packages": packages,
        "has_actions": bool(types.actions),
        "standard_debs": [providers(p)[1] for p in packages if p in standard]
        + (["python3-actionlib"] if types.actions else []),
        "own_interfaces": [p for p in packages if p not in standard],
        "component_names": sorted(v.name for v in views),
        "xml_description": ts.xml_text(" ".join(description.split())),
        "version": _version(thing.version),
        "readme_title": " ".join(title.split()),
        "readme_description": ts.py_comment(description).replace("<", "&lt;").replace(">", "&gt;"),
        "stub_packages": sorted({m.path.split("/")[0] for m in stubs}),
    }
    root = f"{pkg}/"
    tree.add(root + "package.xml", _render("package.xml.j2", **context))
    tree.add(root + "CMakeLists.txt", _render("CMakeLists.txt.j2", **context))
    tree.add(root + "setup.py", _render("setup.py.j2", **context))
    tree.add(root + "README.md", _render("README.md.j2", **context))
    tree.add(root + "mypy.ini", _render("mypy.ini.j2", **context))
    tree.add(root + "ruff.toml", _render("ruff.toml.j2", **context))
    src = f"{root}src/{pkg}/"
    tree.add(src + "__init__.py", _render("src/__init__.py.j2", **context))
    tree.add(src + "py.typed", "")
    tree.add(f"{src}{api.RECORD}.py", api.record_source(model, "ros1"))
    for name in py.SHARED:
        tree.add(src + name, py.shared_source(name))
    tree.add(src + "_runtime.py", verbatim(VERBATIM, "_runtime.py"))
    if types.actions:
        tree.add(src + "_actions.py", verbatim(VERBATIM, "_actions.py"))
    tree.add(src + "components.py", _render("src/components.py.j2", **context))
    tree.add(src + "edge_node.py", _render("src/edge_node.py.j2", **context, script=False))
    # the same code as the rosrun script (catkin_install_python in CMakeLists.txt)
    tree.add(root + "scripts/edge_node", _render("src/edge_node.py.j2", **context, script=True), executable=True)
    tree.add(root + "launch/edge_node.launch", _render("launch/edge_node.launch.j2", **context))
    for name in _FIXED_STUBS + (_ACTION_STUBS if types.actions else ()):
        tree.add(f"{root}stubs/{name}", verbatim(VERBATIM, f"stubs/{name}"))
    packages_done: set[str] = set()
    for module in stubs:
        top = module.path.split("/")[0]
        if top not in packages_done:
            packages_done.add(top)
            tree.add(f"{root}stubs/{top}/__init__.pyi", "")
        tree.add(f"{root}stubs/{module.path}", _render("stubs/messages.pyi.j2", module=module))
    return tree
