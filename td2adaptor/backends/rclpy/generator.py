"""The rclpy backend: an ament_python ROS 2 package of typed component classes, with stubs for its messages.

Everything a template prints is computed here (the view model); the templates in `templates/` only loop and
print, and the run-time modules are copied unchanged (`verbatim/runtime.py`, and `common.py` and `errors.py`
shared with the rospy backend in `backends/_python/verbatim/`). Every TD string reaches the output through
`textsafe`. Output, under `<package>/`: package.xml, setup.py, setup.cfg (also the mypy configuration),
ruff.toml, README.md, resource/<package>, `<package>/` (components, convert, runtime, common, errors, py.typed,
edge_node), `launch/edge_node.launch.py` and `stubs/` (typed stubs of the interface packages used, because
rosidl's Python messages carry no type information, and of the parts of launch/launch_ros the launch file uses).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from td2adaptor.backends import _python as py
from td2adaptor.backends._python import StubClass, StubField, StubModule, import_block
from td2adaptor.backends.rclpy import types as rt
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation import textsafe as ts
from td2adaptor.generation.backend import GeneratedTree, GenOptions
from td2adaptor.generation.templating import render, verbatim
from td2adaptor.model import (
    ActionDef,
    ActionEndpoint,
    ArrayKind,
    Component,
    Failure,
    FieldType,
    MessageDef,
    Model,
    ProcedureRole,
    Role,
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


VERSION = re.compile(r"^[0-9]+\.[0-9]+\.[0-9]+$")
VERBATIM = Path(__file__).parent / "verbatim"
#: copied unchanged: the parts of ROS 2's launch and launch_ros that launch/edge_node.launch.py uses, typed
_LAUNCH_STUBS = (
    "launch/__init__.pyi",
    "launch/actions.pyi",
    "launch/substitutions.pyi",
    "launch_ros/__init__.pyi",
    "launch_ros/actions.pyi",
)

#: names generated modules must not give to message classes: what the runtime modules define, what the
#: templates import besides them, keywords and builtins
RESERVED = py.reserved_names(
    [verbatim(VERBATIM, "runtime.py"), *(py.shared_source(n) for n in py.SHARED)],
    ["annotations", "Any", "Callable", "Mapping", "Sequence", "Node", "NDArray", "Final", "array", "check_fields"],
)


# ---------------------------------------------------------------------------------------------------------
# small helpers


def docstring(paragraphs: Iterable[str | None], indent: str) -> str:
    """A docstring literal of the non-empty paragraphs (each collapsed to one), wrapped and escaped."""
    return py.docstring(paragraphs, indent, margin=8, collapse=True, fallback="(no description)")


def text_paragraphs(text: Text, name: str) -> list[str]:
    """Title and description of an affordance, as docstring paragraphs."""
    first = text.title or name
    out = [first if first.rstrip().endswith((".", "!", "?", ":")) else first + "."]
    if text.description and text.description.strip() != (text.title or "").strip():
        out.extend(p for p in re.split(r"\n\s*\n", text.description) if p.strip())
    return out


def module_of(type_name: str) -> tuple[str, str]:
    """`pkg/msg/Name` → ("pkg.msg", "Name"); `pkg/srv/Name_Request` → ("pkg.srv", "Name_Request")."""
    pkg, kind, short = type_name.split("/")
    return f"{pkg}.{kind}", short


class Namer:
    """Local Python names for interface classes in one module: the short name unless it clashes."""

    def __init__(self, wanted: Iterable[str], reserved: Iterable[str]) -> None:
        wanted = sorted(set(wanted))
        shorts: dict[str, list[str]] = {}
        for full in wanted:
            shorts.setdefault(module_of(full)[1], []).append(full)
        taken = set(reserved)
        self.local: dict[str, str] = {}
        for full in wanted:
            short = module_of(full)[1]
            if len(shorts[short]) == 1 and short not in taken:
                self.local[full] = short
            else:
                self.local[full] = full.split("/")[0] + "_" + short
        self.reserved = frozenset(reserved)

    def __getitem__(self, full: str) -> str:
        return self.local[full]

    def import_pairs(self) -> list[tuple[str, str]]:
        out = []
        for full, local in self.local.items():
            module, short = module_of(full)
            out.append((module, short if local == short else f"{short} as {local}"))
        return out


def converter_name(msg: str) -> str:
    pkg, _, short = msg.split("/")
    return f"to_{pkg}_{short}"


# ---------------------------------------------------------------------------------------------------------
# the view model


@dataclass
class ParamView:
    name: str
    key: str  # the field name as a str literal
    annotation: str
    default: str
    field: str
    convert: str  # expression, the parameter (or mapping item) already substituted
    optional: bool
    check: tuple[str, str, str] | None = None  # `convert` is check(value, what): what names the field in errors

    def assign(self, target: str, indent: int) -> list[str]:
        """`target[key] = convert` as lines at `indent`, as ruff lays them out."""
        return self._lines(f"{target}[{self.key}] = ", "", indent)

    def kwarg(self, indent: int) -> list[str]:
        """`field=convert,` (an argument of the message's constructor) as lines at `indent`."""
        return self._lines(f"{self.field}=", ",", indent)

    def _lines(self, lead: str, tail: str, indent: int) -> list[str]:
        if self.check is None:
            return [f"{lead}{self.convert}{tail}"]
        return py.call_lines(lead, self.check[0], self.check[1:], tail, indent)


@dataclass
class ConstructView:
    method: str
    result: str  # local class name of the message or request it returns
    params: list[ParamView]
    doc: str
    optional: bool  # some parameter may be None: the fields are collected in a dict


@dataclass
class CallView:
    name: str
    attr: str
    srv: str
    request: str
    response: str
    ros_name: str  # Python expression
    failure: str  # "procedure_failure", "success_failure" or "None"
    construct: ConstructView
    returns: str
    doc: str
    async_doc: str
    then_doc: str
    run_id: str | None = None  # `response.state.header.id` for procedure runs
    last_attr: str | None = None  # `self._last_<run>_id`: runs set it, queries and cancels read it
    mission_field: str | None = None  # `request.header.id` for queries and cancels


@dataclass
class ActionView:
    name: str
    attr: str
    action: str  # local class name of the action
    goal: str  # `Fibonacci.Goal`
    result: str
    feedback: str
    ros_name: str  # Python expression
    construct: ConstructView
    doc: str
    async_doc: str
    start_doc: str
    rejoin_doc: str


@dataclass
class TopicView:
    name: str
    attr: str
    msg: str
    ros_name: str
    qos: str
    subscriber: bool
    doc: str
    on_doc: str = ""
    construct: ConstructView | None = None
    serialized_doc: str = ""


@dataclass
class ComponentView:
    name: str
    doc: str
    calls: list[CallView]
    topics: list[TopicView]
    actions: list[ActionView]
    last_ids: list[str]
    value: TopicView | None  # the only subscribed property, for get_value()
    value_doc: str


@dataclass
class ConverterView:
    name: str
    msg: str  # local class name
    fields: list[ParamView]  # convert reads `value["field"]`
    field_names: str  # tuple literal
    type_name: str  # str literal
    doc: str


@dataclass
class PackageView:
    package: str
    version: str
    description_xml: str
    readme_title: str
    readme_description: str
    module_doc: str
    components_doc: str
    exec_depends: list[str]
    components: list[ComponentView]
    component_imports: list[str]
    converters: list[ConverterView]
    convert_imports: list[str]
    stubs: list[StubModule]
    stub_files: list[str]
    exports: list[str]
    export_imports: list[str]
    example: str  # first component, for the README
    timeout: str
    wait_timeout: str
    standard_wheels: list[str]  # PyPI wheels of the standard interface packages it imports (Jazzy)
    own_interfaces: list[str]  # interface packages that come from the robot's own definitions
    has_actions: bool = False


#: besides components and errors
_EXPORTS = ("CancelOutcome", "GoalHandle", "GoalOutcome", "LAST_MISSION", "Spinner", "Started", "spin_in_background")


# ---------------------------------------------------------------------------------------------------------
# building it


def _runtime_module(name: str) -> str:
    """Where components and __init__ import a run-time name from: the shared `.common` or `.goals`, or rclpy's
    `.runtime`."""
    if name in py.common_names():
        return ".common"
    return ".goals" if name in py.goals_names() else ".runtime"


#: the runtime function that finds a failure in a response, by how the response says it (`Failure`)
_FAILURE = {
    Failure.NONE: "None",
    Failure.RESULT: "procedure_failure",
    Failure.SUCCESS: "success_failure",
    Failure.SUCCESS_ONLY: "success_only_failure",
}


def _parts(d: MessageDef | ServiceDef | ActionDef) -> list[MessageDef]:
    """The messages a type is made of: a service's request and response, an action's goal, result, feedback."""
    if isinstance(d, ServiceDef):
        return [d.request, d.response]
    if isinstance(d, ActionDef):
        return [d.goal, d.result, d.feedback]
    return [d]


def _import_name(full: str, local: str) -> str:
    short = module_of(full)[1]
    return short if local == short else f"{short} as {local}"


def _tuple_literal(items: Sequence[str]) -> str:
    if len(items) == 1:
        return f"({ts.py_str(items[0])},)"
    return "(" + ", ".join(ts.py_str(i) for i in items) + ")"


class Builder:
    def __init__(self, model: Model, options: GenOptions, diags: Diagnostics) -> None:
        self.model = model
        self.types: TypeTable = model.ros2
        self.diags = diags
        self.partial = options.partial
        self.package = options.package_name or model.package_name
        # what components.py refers to, so that it imports exactly that
        self.msg_used: set[str] = set()
        self.conv_used: set[str] = set()
        self.conv_checks: set[str] = set()  # the number checks convert.py calls (from .common)
        self.runtime_used: set[str] = {"DEFAULT_TIMEOUT", "DEFAULT_WAIT_TIMEOUT", "check_robot_name", "check_timeout"}
        self.std_used: set[tuple[str, str]] = set()

    # -- what the model asks for, and whether rclpy can express it

    def _skip(self, comp: Component, member: str, pointer: str, problem: str) -> None:
        if self.partial:
            self.diags.warning("GEN821", f"rclpy backend: skipped {comp.name}.{member}: {problem}", pointer)
        else:
            self.diags.error(
                "GEN820", f"rclpy backend: {comp.name}.{member}: {problem}", pointer, hint="--partial skips it"
            )

    def _unresolved(self, type_name: str) -> str:
        why = self.types.why_unavailable(type_name)
        if why is not None:
            return f"its type {type_name} is for ROS 1 only ({why})"
        return f"type {type_name} does not resolve for ROS 2 (Jazzy)"

    def usable_services(self, comp: Component) -> list[ServiceEndpoint]:
        out = []
        for svc in comp.services:
            if "/action/" in svc.type_name:
                self._skip(comp, svc.name, svc.pointer, "ROS 2 actions are not generated yet")
            elif not isinstance(self.types.get(svc.type_name), ServiceDef):
                self._skip(comp, svc.name, svc.pointer, self._unresolved(svc.type_name))
            else:
                out.append(svc)
        return out

    def usable_actions(self, comp: Component) -> list[ActionEndpoint]:
        out = []
        for action in comp.actions:
            if isinstance(self.types.get(action.type_name), ActionDef):
                out.append(action)
            else:
                self._skip(comp, action.name, action.pointer, self._unresolved(action.type_name))
        return out

    def usable_topics(self, comp: Component) -> list[TopicEndpoint]:
        out = []
        for topic in comp.topics:
            if isinstance(self.types.get(topic.type_name), MessageDef):
                out.append(topic)
            else:
                self._skip(comp, topic.name, topic.pointer, self._unresolved(topic.type_name))
        return out

    def check_names(
        self,
        comp: Component,
        services: list[ServiceEndpoint],
        topics: list[TopicEndpoint],
        actions: Sequence[ActionEndpoint] = (),
    ) -> bool:
        """Generated method names must not clash (e.g. an action and a property of the same name): the
        contract's one check (`genapi.clashes`)."""
        found = api.clashes(
            [s.name for s in services],
            [a.name for a in actions],
            [t.name for t in topics if t.role is Role.SUBSCRIBER],
            [t.name for t in topics if t.role is not Role.SUBSCRIBER],
        )
        for member, owner, other in found:
            self.diags.error(
                "GEN822",
                f"rclpy backend: {comp.name}: method {member} of {owner} clashes with {other}",
                hint="rename one of the affordances",
            )
        return not found

    # -- types

    def message(self, name: str) -> MessageDef:
        return self.types.message(name)

    def reachable(self, roots: Iterable[str]) -> list[str]:
        """Message types reachable from `roots` through message fields, sorted."""
        seen: set[str] = set()
        todo = list(roots)
        while todo:
            name = todo.pop()
            if name not in seen:
                seen.add(name)
                todo.extend(f.type.base for f in self.message(name).fields if f.type.is_message)
        return sorted(seen)

    @staticmethod
    def type_label(name: str) -> str:
        for suffix in ("_Request", "_Response"):
            if name.endswith(suffix):
                return name[: -len(suffix)]
        return name

    # -- names in the generated code

    def ros_name_expr(self, name: RosName) -> str:
        if name.namespaced:
            self.runtime_used.add("in_namespace")
            return f"in_namespace({ts.py_str(name.path)}, self._namespace)"
        return ts.py_str(name.path)

    @staticmethod
    def ros_name_doc(name: RosName) -> str:
        return f"/<robot_name>/{name.path}" if name.namespaced else name.path

    # -- the parts

    def params(self, msg: MessageDef, namer: Namer, *, mapping: bool) -> list[ParamView]:
        """Parameters of a `construct_*` method (mapping=False) or the field conversions of a converter."""
        out = []
        taken = RESERVED | set(namer.local.values())
        for f in msg.fields:
            local = namer[f.type.base] if f.type.is_message else ""
            conv = converter_name(f.type.base) if f.type.is_message else None
            name = py.param_name(f.name, taken)
            p = rt.param(f, local, conv, name)
            value = f"value[{ts.py_str(f.name)}]" if mapping else name
            what = ts.py_str(f"{msg.name}.{f.name}" if mapping else f.name)  # a converter's field: of which type
            if p.check is not None:
                (self.conv_checks if mapping else self.runtime_used).add(p.check)
            if not mapping:
                if f.type.is_message:
                    self.msg_used.add(f.type.base)
                    self.conv_used.add(converter_name(f.type.base))
                    self.std_used |= {("collections.abc", "Mapping"), ("typing", "Any")}
                if f.type.array is not ArrayKind.NONE:
                    self.std_used.add(("collections.abc", "Sequence"))
            out.append(
                ParamView(
                    p.name,
                    ts.py_str(f.name),
                    p.annotation,
                    p.default,
                    f.name,
                    p.convert.format(v=value, what=what),
                    p.optional,
                    None if p.check is None else (p.check, value, what),
                )
            )
        return out

    def construct(self, method: str, msg: MessageDef, result: str, namer: Namer, what: str) -> ConstructView:
        doc = docstring(
            [
                f"Build {what} ({self.type_label(msg.name)}).",
                "Every field is a keyword argument with its ROS default. Messages may also be given as mappings "
                "of their fields (nested too), arrays as any sequence; None keeps the field's ROS default.",
            ],
            "        ",
        )
        params = self.params(msg, namer, mapping=False)
        # a dict of fields when some may be left out, or a field name is not usable as a keyword argument
        optional = any(p.optional or p.name != p.field for p in params)
        if optional:
            self.std_used.add(("typing", "Any"))
        return ConstructView(method, result, params, doc, optional)

    def call_view(self, comp: Component, svc: ServiceEndpoint, namer: Namer) -> CallView:
        sdef = self.types.service(svc.type_name)
        self.msg_used |= {svc.type_name, sdef.request.name, sdef.response.name}
        self.runtime_used.add("ServiceClient")
        self.std_used.add(("collections.abc", "Callable"))  # call_X_then's on_done
        self.std_used.add((".errors", "AdaptorError"))
        srv, req, resp = namer[svc.type_name], namer[sdef.request.name], namer[sdef.response.name]
        proc = comp.procedure_of(svc.name)
        run_id = last_attr = mission_field = None
        returns = resp
        body = [*text_paragraphs(svc.text, svc.name), f"Service {self.ros_name_doc(svc.ros_name)} ({svc.type_name})."]
        if proc is not None and proc.mission_id and svc.procedure_role is ProcedureRole.RUN:
            run_id = "response." + ".".join(proc.mission_id)
            last_attr = f"self._last_{svc.name}_id"
            returns = f"Started[{resp}]"
            self.runtime_used.add("Started")
            body.append(
                f"Returns Started(mission_id, response); the mission id is {'/'.join(proc.mission_id)} of the "
                "response, and the procedure's query and cancel methods use it when given no mission_id."
            )
        elif proc is not None and svc.procedure_role in (ProcedureRole.QUERY, ProcedureRole.CANCEL):
            path = ".".join(proc.slot(svc.procedure_role.value))
            if path:
                mission_field = "request." + path
                last_attr = f"self._last_{proc.run}_id"
                self.runtime_used.add("LAST_MISSION")
                body.append(
                    f"mission_id selects the procedure: it is written to {path.replace('.', '/')} of the request "
                    f"(of an explicit request too). Default: the id this object's last {api.CALL(proc.run)} returned; "
                    "-1 (LAST_MISSION: the robot's last procedure) only when it made none yet."
                )
        body.append(f"request: None sends {api.CONSTRUCT_REQUEST(svc.name)}() (all ROS defaults).")
        failure = _FAILURE[svc.failure]
        if failure != "None":
            self.runtime_used.add(failure)
        body.append(
            "Raises ServiceUnavailable when no server appears within wait_timeout, CallTimeout when the response "
            "takes longer than timeout (default: the component's), CallFailed "
            + ("when the robot reports an error (with its message)." if failure != "None" else "if it is cancelled.")
        )
        what = f"the request of {svc.name}"
        construct = self.construct(api.CONSTRUCT_REQUEST(svc.name), sdef.request, req, namer, what)
        async_doc = docstring(
            [
                f"{api.CALL(svc.name)}, awaitable: await it in a coroutine callback of the node's executor (or in any "
                "coroutine while an executor spins the node). No thread blocks; the errors are the same."
            ],
            "        ",
        )
        then_doc = docstring(
            [
                f"{api.CALL(svc.name)} without waiting: sends the request and returns True at once; "
                "on_done(answer, None) is called with the answer "
                f"{api.CALL(svc.name)} would return, or on_done(None, error) with the error it would raise, once, on "
                "the node's responses reader thread (it must not block). False, and nothing sent, when the call "
                "cannot be made without waiting (no server known yet, or no responses reader of this package's "
                f"Spinner serves the node): make it with {api.CALL(svc.name)}.",
            ],
            "        ",
        )
        return CallView(
            name=svc.name,
            attr=f"self._{svc.name}",
            srv=srv,
            request=req,
            response=resp,
            ros_name=self.ros_name_expr(svc.ros_name),
            failure=failure,
            construct=construct,
            returns=returns,
            doc=docstring(body, "        "),
            async_doc=async_doc,
            then_doc=then_doc,
            run_id=run_id,
            last_attr=last_attr,
            mission_field=mission_field,
        )

    def action_view(self, action: ActionEndpoint, namer: Namer) -> ActionView:
        adef = self.types.action(action.type_name)
        self.msg_used.add(action.type_name)
        self.runtime_used |= {"ActionGoalClient", "GoalHandle", "GoalOutcome"}
        self.std_used.add(("collections.abc", "Callable"))
        local = namer[action.type_name]
        goal, result, feedback = f"{local}.Goal", f"{local}.Result", f"{local}.Feedback"
        body = [
            *text_paragraphs(action.text, action.name),
            f"ROS 2 action {self.ros_name_doc(action.ros_name)} ({action.type_name}).",
            f"Sends goal (None sends {api.CONSTRUCT_GOAL(action.name)}(), all ROS defaults) and returns the accepted "
            "goal's GoalHandle: goal_id, status, on_feedback(callback), feedback(timeout=...) to iterate over the "
            "feedback until the goal ends, result(timeout=...) and cancel(timeout=...), and for coroutines "
            "feedback_async (async for), result_async and cancel_async. Its waits default to timeout (default: "
            "the component's).",
            "Raises ServiceUnavailable when no action server appears within wait_timeout, CallTimeout when the "
            "server does not answer within timeout, GoalRejected when it refuses the goal; result() raises "
            "GoalAborted or GoalCanceled when the goal does not succeed.",
        ]
        construct = self.construct(
            api.CONSTRUCT_GOAL(action.name), adef.goal, goal, namer, f"the goal of {action.name}"
        )
        return ActionView(
            name=action.name,
            attr=f"self._{action.name}",
            action=local,
            goal=goal,
            result=result,
            feedback=feedback,
            ros_name=self.ros_name_expr(action.ros_name),
            construct=construct,
            doc=docstring(body, "        "),
            async_doc=docstring(
                [
                    f"{api.SEND(action.name)}, awaitable: await it in a coroutine callback of the node's executor "
                    "(or in "
                    "any coroutine while an executor spins the node). No thread blocks; the errors are the same."
                ],
                "        ",
            ),
            start_doc=docstring(
                [
                    f"{api.SEND(action.name)} without waiting: returns the goal's GoalHandle at once (its goal_id is "
                    "known) and tells what happens to the callbacks: on_accepted() once the server accepted the "
                    "goal, on_status(status) at each change of status while it runs, on_feedback(message) with "
                    "each feedback message (also those that came before the acceptance), in order, then exactly "
                    "one on_done(outcome), a GoalOutcome: status succeeded, canceled, aborted, rejected or lost "
                    "(no server within wait_timeout, no answer within timeout, the server went away), result, "
                    "error. on_done waits feedback_grace seconds (default: the runtime's FEEDBACK_GRACE) after the "
                    "result for feedback still on its way.",
                    "The callbacks run in the thread of the executor that spins the node, never two at once for "
                    "one goal: they must return quickly (hand the event on to your own loop). The handle's "
                    "feedback(), result() and cancel() read the same record; request_cancel(on_done) cancels "
                    "without waiting. Raises only TypeError (a goal of another type) and ValueError (a bad "
                    "timeout).",
                ],
                "        ",
            ),
            rejoin_doc=docstring(
                [
                    f"Follow the goal goal_id (its 32 hex digits) that the server accepted from another client (this "
                    f"process before a restart, another process), as {api.START(action.name)} follows its own: its "
                    "GoalHandle at once, on_accepted() once the server is there, then its status, the feedback from "
                    "now on and exactly one on_done(outcome). The server answers the goal's result request: its "
                    "real end, or, when it does not know the goal (ended longer ago than it keeps results, or "
                    "never its), the goal ends lost. Raises only ValueError (a bad id or timeout).",
                ],
                "        ",
            ),
        )

    def topic_view(self, topic: TopicEndpoint, namer: Namer) -> TopicView:
        self.msg_used.add(topic.type_name)
        self.runtime_used.add("qos_profile")
        q = topic.qos
        qos = (
            f"qos_profile({ts.py_str(q.reliability.value)}, {ts.py_str(q.durability.value)}, "
            f"{ts.py_str(q.history.value)}, {int(q.depth)})"
        )
        body = [
            *text_paragraphs(topic.text, topic.name),
            f"Topic {self.ros_name_doc(topic.ros_name)} ({topic.type_name}).",
        ]
        msg = namer[topic.type_name]
        ros_name = self.ros_name_expr(topic.ros_name)
        if topic.role is Role.SUBSCRIBER:
            self.runtime_used.add("TopicSubscriber")
            self.std_used.add(("collections.abc", "Callable"))
            body.append(
                "Returns the latest message, waiting at most timeout seconds (default: the component's timeout) "
                "for the first one; raises NoMessage when none arrived by then."
            )
            on_doc = docstring(
                [
                    f"Call callback with every {topic.name} message, in the thread that takes the node's messages "
                    "(the executor's; spin_in_background's subscription thread); it must not block.",
                    "Returns a function that removes the callback again.",
                ],
                "        ",
            )
            serialized_doc = docstring(
                [
                    f"Call callback with every {topic.name} message as it arrived: its serialized (CDR) bytes, in the "
                    "thread that takes the node's messages.",
                    "For relaying every message without converting it "
                    f"(rclpy.serialization.deserialize_message(data, {msg}) gives the message). Returns a function "
                    "that removes the callback again.",
                ],
                "        ",
            )
            return TopicView(
                topic.name,
                f"self._{topic.name}",
                msg,
                ros_name,
                qos,
                True,
                docstring(body, "        "),
                on_doc,
                serialized_doc=serialized_doc,
            )
        self.runtime_used.add("TopicPublisher")
        body.append(f"Publishes msg (build it with {api.CONSTRUCT_MESSAGE(topic.name)}).")
        construct = self.construct(
            api.CONSTRUCT_MESSAGE(topic.name), self.message(topic.type_name), msg, namer, f"the message of {topic.name}"
        )
        return TopicView(
            topic.name, f"self._{topic.name}", msg, ros_name, qos, False, docstring(body, "        "), "", construct
        )

    def component_view(
        self,
        comp: Component,
        services: list[ServiceEndpoint],
        topics: list[TopicEndpoint],
        actions: list[ActionEndpoint],
        namer: Namer,
    ) -> ComponentView:
        parts = []
        named = [s.name for s in services] + [a.name for a in actions]
        if named:
            parts.append(("actions " if len(named) > 1 else "action ") + ", ".join(named))
        if topics:
            parts.append(("properties " if len(topics) > 1 else "property ") + ", ".join(t.name for t in topics))
        doc = docstring(
            [
                f"{comp.name}: the {' and the '.join(parts) or 'nothing'} of {self.model.thing.title}.",
                "node is the rclpy node that owns the clients, publishers and subscriptions; robot_name the robot "
                "namespace (it replaces {{robotName}} in the TD's names); timeout the default seconds to wait for "
                "an answer, wait_timeout for a service to appear. The blocking methods need an executor that "
                "spins the node in another thread (runtime.spin_in_background).",
            ],
            "    ",
        )
        calls = [self.call_view(comp, s, namer) for s in services]
        tviews = [self.topic_view(t, namer) for t in topics]
        aviews = [self.action_view(a, namer) for a in actions]
        last_ids = sorted({c.last_attr for c in calls if c.run_id and c.last_attr})
        subs = [t for t in tviews if t.subscriber]
        value = subs[0] if len(subs) == 1 else None
        value_doc = (
            docstring(
                [f"The component's only subscribed property: {api.GET(value.name)}(timeout=timeout)."], "        "
            )
            if value is not None
            else ""
        )
        return ComponentView(comp.name, doc, calls, tviews, aviews, last_ids, value, value_doc)

    # -- stubs

    def stubs(self, wanted: set[str]) -> list[StubModule]:
        """One stub module per interface package and kind (msg, srv), with the types the package uses."""
        by_module: dict[str, list[str]] = {}
        for name in wanted:
            by_module.setdefault(module_of(name)[0], []).append(name)
        out = []
        for module in sorted(by_module):
            pkg, kind = module.split(".")
            defs: list[MessageDef | ServiceDef | ActionDef] = []
            for name in sorted(by_module[module]):
                found = self.types.get(name)
                assert isinstance(found, (MessageDef, ServiceDef, ActionDef))
                defs.append(found)
            own: set[str] = set()
            refs: set[str] = set()
            for d in defs:
                parts = _parts(d)
                own |= {d.name, *(m.name for m in parts)}
                refs |= {f.type.base for m in parts for f in m.fields if f.type.is_message}
            namer = Namer(sorted(refs - own), {module_of(n)[1] for n in own} | RESERVED)
            local = {n: module_of(n)[1] for n in own} | namer.local
            plain: set[str] = set()
            extra: set[tuple[str, str]] = set()
            classes: list[StubClass] = []
            for d in defs:
                if isinstance(d, ServiceDef):
                    classes += [self.stub_class(m, local, plain, extra) for m in (d.request, d.response)]
                    classes.append(
                        StubClass(
                            module_of(d.name)[1], [], [], module_of(d.request.name)[1], module_of(d.response.name)[1]
                        )
                    )
                elif isinstance(d, ActionDef):
                    classes += [self.stub_class(m, local, plain, extra) for m in (d.goal, d.result, d.feedback)]
                    aliases = tuple(
                        (alias, module_of(m.name)[1])
                        for alias, m in (("Goal", d.goal), ("Result", d.result), ("Feedback", d.feedback))
                    )
                    classes.append(StubClass(module_of(d.name)[1], [], [], aliases=aliases))
                else:
                    classes.append(self.stub_class(d, local, plain, extra))
            what = {"srv": "services", "action": "actions"}.get(kind, "messages")
            doc = ts.py_docstring(
                f"The {pkg} {what} {self.package} uses, typed (generated by td2adaptor; partial).", ""
            )
            out.append(
                StubModule(
                    f"stubs/{pkg}/{kind}/__init__.pyi",
                    doc,
                    import_block(namer.import_pairs() + sorted(extra), plain),
                    classes,
                )
            )
        for pkg in sorted({m.path.split("/")[1] for m in out}):
            doc = ts.py_docstring(f"Stubs of the {pkg} interfaces {self.package} uses (partial).", "")
            out.append(StubModule(f"stubs/{pkg}/__init__.pyi", doc, [], []))
        return sorted(out, key=lambda m: m.path)

    def stub_class(
        self, msg: MessageDef, local: dict[str, str], plain: set[str], extra: set[tuple[str, str]]
    ) -> StubClass:
        consts = []
        for c in msg.constants:
            extra.add(("typing", "Final"))
            value = rt.literal(FieldType(c.type), c.value) if c.type in rt.SCALAR else None
            consts.append(f"{c.name}: Final = {value}" if value is not None else f"{c.name}: Final[object]")
        fields = []
        for f in msg.fields:
            if rt.needs_array(f.type):
                plain.add("array")
            if rt.needs_numpy(f.type):
                extra |= {("numpy.typing", "NDArray"), ("typing", "Any")}
            if f.type.array is not ArrayKind.NONE:
                extra.add(("collections.abc", "Sequence"))
            name = local[f.type.base] if f.type.is_message else ""
            fields.append(StubField(f.name, rt.getter(f.type, name), rt.init_param(f.type, name)))
        return StubClass(module_of(msg.name)[1], consts, fields)

    # -- the whole package

    def build(self) -> PackageView | None:
        selected: list[tuple[Component, list[ServiceEndpoint], list[TopicEndpoint], list[ActionEndpoint]]] = []
        ok = True
        for comp in self.model.components:
            services, topics = self.usable_services(comp), self.usable_topics(comp)
            actions = self.usable_actions(comp)
            ok = self.check_names(comp, services, topics, actions) and ok
            selected.append((comp, services, topics, actions))
        if not ok or any(d.severity is Severity.ERROR for d in self.diags):
            return None

        # every interface type components.py may name, with clash-free local names
        candidates: set[str] = set()
        roots: set[str] = set()  # message types of constructor parameters
        for _comp, services, topics, actions in selected:
            for a in actions:
                adef = self.types.action(a.type_name)
                candidates.add(a.type_name)
                roots |= {f.type.base for f in adef.goal.fields if f.type.is_message}
            for s in services:
                sdef = self.types.service(s.type_name)
                candidates |= {s.type_name, sdef.request.name, sdef.response.name}
                roots |= {f.type.base for f in sdef.request.fields if f.type.is_message}
            for t in topics:
                candidates.add(t.type_name)
                if t.role is Role.PUBLISHER:
                    roots |= {f.type.base for f in self.message(t.type_name).fields if f.type.is_message}
        namer = Namer(candidates | roots, RESERVED | {c[0].name for c in selected})
        components = [self.component_view(c, s, t, a, namer) for c, s, t, a in selected]
        pairs = [(module_of(f)[0], _import_name(f, namer[f])) for f in sorted(self.msg_used)]
        pairs += [(".convert", c) for c in sorted(self.conv_used)]
        pairs += [(_runtime_module(n), n) for n in sorted(self.runtime_used)]
        pairs += sorted(self.std_used)
        pairs.append(("rclpy.node", "Node"))

        # converters for every message reachable from constructor parameters
        conv_types = self.reachable(roots)
        conv_namer = Namer(conv_types, RESERVED)
        converters = []
        for name in conv_types:
            msg = self.message(name)
            converters.append(
                ConverterView(
                    name=converter_name(name),
                    msg=conv_namer[name],
                    fields=self.params(msg, conv_namer, mapping=True),
                    field_names=_tuple_literal([f.name for f in msg.fields]),
                    type_name=ts.py_str(name),
                    doc=docstring(
                        [f"{name} from itself, or from a mapping of its fields (nested mappings too)."], "    "
                    ),
                )
            )
        convert_pairs = conv_namer.import_pairs() + [("collections.abc", "Mapping")]
        convert_pairs += [(".common", name) for name in sorted(self.conv_checks)]
        convert_pairs.append(("typing", "cast"))  # check_fields uses it
        if converters:  # `Any` is only in converter signatures: a package that sends nothing has none (F401)
            convert_pairs.append(("typing", "Any"))

        # stubs: every type the package touches, with everything those refer to
        stub_types: set[str] = set(conv_types)
        for name in candidates:
            found = self.types.get(name)
            if isinstance(found, ServiceDef):
                stub_types.add(name)
                for m in (found.request, found.response):
                    stub_types |= set(self.reachable(f.type.base for f in m.fields if f.type.is_message))
            elif isinstance(found, ActionDef):
                stub_types.add(name)
                for m in (found.goal, found.result, found.feedback):
                    stub_types |= set(self.reachable(f.type.base for f in m.fields if f.type.is_message))
            elif isinstance(found, MessageDef) and "/msg/" in name:
                stub_types |= set(self.reachable([name]))
        stubs = self.stubs(stub_types)

        interfaces = {n.split("/")[0] for n in stub_types}
        thing = self.model.thing
        description = thing.description or ""
        summary = f"ROS 2 (rclpy) adaptor for {thing.title}, generated by td2adaptor from its Thing Description."
        errors = sorted(py.error_classes())
        exports = [c.name for c in components] + errors + list(_EXPORTS)
        export_pairs = [(".components", c.name) for c in components]
        export_pairs += [(".errors", n) for n in errors] + [(_runtime_module(n), n) for n in _EXPORTS]
        return PackageView(
            package=self.package,
            version=thing.version if thing.version and VERSION.match(thing.version) else "0.1.0",
            description_xml=ts.xml_text(f"{summary} {description}".strip()),
            readme_title=ts.xml_text(ts.py_comment(thing.title)),
            readme_description=ts.xml_text(ts.py_comment(description)),
            module_doc=docstring(
                [
                    f"ROS 2 (rclpy) adaptor for {thing.title}: one class per component of its Thing Description.",
                    description,
                    "Generated by td2adaptor; do not edit.",
                ],
                "",
            ),
            components_doc=docstring(
                [
                    f"The component classes of {self.package}, in Thing Description order.",
                    "Generated by td2adaptor; do not edit.",
                ],
                "",
            ),
            exec_depends=sorted({n.split("/")[0] for n in stub_types} | {"rclpy", "launch_ros"}),
            standard_wheels=[providers(p)[0] for p in sorted(interfaces) if p in self.model.standard_packages],
            own_interfaces=[p for p in sorted(interfaces) if p not in self.model.standard_packages],
            components=components,
            component_imports=import_block(pairs),
            converters=converters,
            convert_imports=import_block(convert_pairs),
            stubs=stubs,
            stub_files=[m.path for m in stubs],
            exports=exports,
            export_imports=import_block(export_pairs),
            example=components[0].name if components else "",
            timeout=py.constant("DEFAULT_TIMEOUT"),
            wait_timeout=py.constant("DEFAULT_WAIT_TIMEOUT"),
            has_actions=any(c.actions for c in components),
        )


# ---------------------------------------------------------------------------------------------------------
# rendering


def _render(template: str, **context: object) -> str:
    return render(TEMPLATES, template, **context)


def generate(model: Model, options: GenOptions, diags: Diagnostics) -> GeneratedTree:
    """The ament_python package for `model`, under `<package>/`."""
    tree = GeneratedTree()
    view = Builder(model, options, diags).build()
    if view is None:
        return tree
    root = view.package
    src = f"{root}/{root}"
    ctx: dict[str, object] = {
        "v": view,
        "package": view.package,
        "timeout": view.timeout,
        "wait_timeout": view.wait_timeout,
    }
    for name in ("package.xml", "setup.py", "setup.cfg", "ruff.toml", "README.md"):
        tree.add(f"{root}/{name}", _render(f"{name}.j2", **ctx))
    tree.add(f"{root}/resource/{root}", "")
    for name in ("__init__.py", "convert.py", "components.py", "edge_node.py"):
        tree.add(f"{src}/{name}", _render(f"package/{name}.j2", **ctx))
    tree.add(f"{src}/runtime.py", verbatim(VERBATIM, "runtime.py"))
    for name in py.SHARED:
        tree.add(f"{src}/{name}", py.shared_source(name))
    tree.add(f"{src}/py.typed", "")
    tree.add(f"{src}/{api.RECORD}.py", api.record_source(model, "ros2"))
    for module in view.stubs:
        tree.add(f"{root}/{module.path}", _render("stubs/module.pyi.j2", m=module, **ctx))
    tree.add(f"{root}/launch/edge_node.launch.py", _render("launch/edge_node.launch.py.j2", **ctx))
    taken = {m.path.split("/")[1] for m in view.stubs}  # an interface package named launch keeps its stubs
    for name in _LAUNCH_STUBS:  # for mypy and pyright on the launch file only: not installed
        if name.split("/")[0] not in taken:
            tree.add(f"{root}/stubs/{name}", verbatim(VERBATIM, f"stubs/{name}"))
    return tree
