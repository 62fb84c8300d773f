"""Lower raw ROS bindings into the canonical model: check names, group components, link procedures,
resolve types for ROS 1 and ROS 2, and cross-check TD data schemas against the message definitions.
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity, pointer_join
from td2adaptor.frontend.extract import BINDING, REFERENCE, RawEndpoint, obj
from td2adaptor.lowering.distros import BACKENDS, DISTROS, LABELS, Loss, loss, other, split_problems, usable
from td2adaptor.lowering.procstate import READING_KEYS, RoleInfo, check_reading, failure_of, parse_reading
from td2adaptor.lowering.rosnames import (
    BINDING_PLACEHOLDER,
    REFERENCE_PLACEHOLDER,
    identifier_problem,
    name_problems,
    package_name,
    package_name_problem,
    split_namespace,
)
from td2adaptor.model import (
    ActionEndpoint,
    Component,
    Interface,
    Model,
    Procedure,
    ProcedureRole,
    Role,
    Ros1Digest,
    ServiceDef,
    ServiceEndpoint,
    Thing,
    TopicEndpoint,
    TypeTable,
    freeze,
)
from td2adaptor.model.primitives import INTEGERS

if TYPE_CHECKING:
    from td2adaptor.rostypes.registry import TypeRegistry

#: ROS name suffixes and affordance-name suffixes that identify procedure roles in the reference dialect.
_RUN_SUFFIXES = ("/add",)
_QUERY_SUFFIXES = ("/query_state", "/query")
_CANCEL_SUFFIXES = ("/cancel",)
_NAME_ROLE = (
    (re.compile(r"(Run)$"), ProcedureRole.RUN),
    (re.compile(r"(Query)$"), ProcedureRole.QUERY),
    (re.compile(r"(Cancel|Cancle)$"), ProcedureRole.CANCEL),
)


@dataclass
class _Endpoint:
    raw: RawEndpoint
    component: str
    ros_name: Any
    type_name: str
    procedure_role: ProcedureRole = ProcedureRole.NONE
    errors: bool = False


@dataclass
class _Group:
    name: str
    pointer: str
    endpoints: list[_Endpoint] = field(default_factory=list)


def thing_of(td: Mapping[str, Any], fallback_title: str) -> Thing:
    title = td.get("title") if isinstance(td.get("title"), str) and td.get("title") else fallback_title
    master = td.get("rosv:masterURI", td.get("ros:masterURI"))
    version = obj(td.get("version")).get("instance")
    links = td.get("links")
    types = [
        lk["href"]
        for lk in (links if isinstance(links, list) else [])
        if isinstance(lk, dict) and lk.get("rel") == "type" and isinstance(lk.get("href"), str)
    ]
    return Thing(
        title=str(title),
        id=td["id"] if isinstance(td.get("id"), str) else None,
        description=td["description"] if isinstance(td.get("description"), str) else None,
        version=version if isinstance(version, str) else None,
        master_uri=master if isinstance(master, str) else None,
        security=freeze(obj(td.get("securityDefinitions"))),
        model=types[0] if types else None,
    )


def lower(
    td: Mapping[str, Any],
    raws: Sequence[RawEndpoint],
    diags: Diagnostics,
    *,
    interface_dirs: Sequence[Path] = (),
    package: str | None = None,
    fallback_title: str = "thing",
    registries: Mapping[str, TypeRegistry] | None = None,
) -> Model | None:
    """Build the canonical model; returns None when errors make a model meaningless."""
    errors_before = len(diags.errors())
    thing = thing_of(td, fallback_title)
    pkg = package or package_name(thing.title)
    problem = package_name_problem(pkg)
    if problem:
        diags.error("ROS432", f"package name {pkg!r} {problem}", "/title" if package is None else "")
    if not raws and not _attempts_binding(td):  # when every binding was refused, its errors say why
        diags.warning(
            "ROS400",
            "no affordance is bound to ROS; there is nothing to generate",
            "",
            "bind actions to ROS services and properties to topics (docs/binding.md)",
        )
    _check_unbound_actions(td, raws, diags)
    endpoints = [ep for ep in (_endpoint(raw, diags) for raw in raws) if ep is not None]
    _check_duplicate_names(endpoints, diags)
    _check_relative_names(endpoints, diags)
    groups = _group(endpoints, diags)
    procedures = {g.name: _procedures(g, diags) for g in groups}
    found = Diagnostics()
    own: dict[str, list[Diagnostic]] = {d: [] for d in DISTROS}
    if registries is not None:
        regs = registries
    else:
        regs, own = _registries(interface_dirs, found)
    tables, closures = _resolve_types(endpoints, regs, own, diags)
    _report_interface_problems(found, endpoints, closures, diags)
    for g in groups:
        procedures[g.name] = tuple(_mission_ids(g, procedures[g.name], tables, diags))
        procedures[g.name] = tuple(check_reading(proc, _roles(g, proc), tables, diags) for proc in procedures[g.name])
    _crosscheck(endpoints, tables, diags, ros1_first=thing.master_uri is not None)
    if len(diags.errors()) > errors_before:
        return None
    components = tuple(
        Component(
            name=g.name,
            services=tuple(_service(ep, tables) for ep in g.endpoints if ep.raw.interface is Interface.SERVICE),
            topics=tuple(_topic(ep) for ep in g.endpoints if ep.raw.interface is Interface.TOPIC),
            procedures=procedures[g.name],
            actions=tuple(_action(ep) for ep in g.endpoints if ep.raw.interface is Interface.ACTION),
        )
        for g in groups
    )
    return Model(thing, pkg, components, tables["ros1"], tables["ros2"], _standard_packages(tables, regs))


# ---------------------------------------------------------------------------------------------------------


def _attempts_binding(td: Mapping[str, Any]) -> bool:
    """Whether any form of the TD carries ROS binding terms (`rosv:`, or the reference dialect's `ros:`)."""
    for kind in ("properties", "actions", "events"):
        affordances = td.get(kind)
        for aff in affordances.values() if isinstance(affordances, Mapping) else ():
            forms = aff.get("forms") if isinstance(aff, Mapping) else None
            for form in forms if isinstance(forms, list) else ():
                if isinstance(form, Mapping) and any(str(k).startswith(("rosv:", "ros:")) for k in form):
                    return True
    return False


def _check_unbound_actions(td: Mapping[str, Any], raws: Sequence[RawEndpoint], diags: Diagnostics) -> None:
    if not raws:
        return
    bound = {r.pointer for r in raws}
    for name, aff in obj(td.get("actions")).items():
        ptr = pointer_join("", "actions", name)
        if ptr not in bound and isinstance(aff, dict):
            diags.error(
                "ROS401",
                f"action {name!r} is not bound to a ROS service",
                ptr,
                "add a form with rosv:name and rosv:type (docs/binding.md)",
            )


def _endpoint(raw: RawEndpoint, diags: Diagnostics) -> _Endpoint | None:
    from td2adaptor.rostypes.names import file_name_problem, hidden_action_part, normalize_type_name

    what = f"{raw.kind} {raw.name!r}"
    ok = True
    problem = identifier_problem(raw.name)
    if problem:
        diags.error(
            "ROS431",
            f"{what}: the name {problem}; generated method names are made from it",
            raw.pointer,
            "rename the affordance (e.g. camelCase letters and digits)",
        )
        ok = False
    ros_name, placeholder = split_namespace(raw.ros_name.value)
    for p in name_problems(ros_name):
        diags.error("ROS410", f"{what}: ROS name {raw.ros_name.value!r}: {p}", raw.ros_name.pointer)
        ok = False
    if raw.dialect == BINDING and placeholder == REFERENCE_PLACEHOLDER:
        diags.warning(
            "ROS411",
            f"{what}: '/{REFERENCE_PLACEHOLDER}' is the reference system's namespace placeholder",
            raw.ros_name.pointer,
            f"write '/{BINDING_PLACEHOLDER}/...' in the td2adaptor binding",
        )
    _check_href(raw, ros_name, diags)
    kind = {Interface.SERVICE: "srv", Interface.TOPIC: "msg", Interface.ACTION: "action"}[raw.interface]
    type_name = normalize_type_name(raw.type_name.value, kind)  # type: ignore[arg-type]
    hidden = hidden_action_part(raw.type_name.value)
    if hidden is not None:
        action, part = hidden
        diags.error(
            "ROS429",
            f"{what}: {raw.type_name.value!r} is the {part} type ROS 2 derives for action {action}: its hidden "
            "services and topic are not bound one by one",
            raw.type_name.pointer,
            f'bind the action itself: "rosv:interface": "action", "rosv:type": "{action}" (goal as input, result '
            "as output; the adaptors send goals, follow feedback and cancel)",
        )
        return None
    if type_name is None:
        diags.error(
            "ROS420",
            f"{what}: {raw.type_name.value!r} is not a ROS interface type name",
            raw.type_name.pointer,
            f"write it as pkg/{kind}/Name",
        )
        ok = False
    elif type_name.split("/")[1] != kind:
        diags.error(
            "ROS421",
            f"{what}: a ROS {raw.interface.value} needs a {kind} type, not {type_name!r}",
            raw.type_name.pointer,
            _interface_hint(raw, type_name.split("/")[1]),
        )
        ok = False
    elif (too_long := file_name_problem(type_name)) is not None:
        diags.error(
            "ROS433",
            f"{what}: type {type_name[:40] + '…'!r} ({len(type_name)} characters) cannot be an interface type: "
            f"{too_long}",
            raw.type_name.pointer,
            "give the type's real name (pkg/msg/Name, pkg/srv/Name or pkg/action/Name)",
        )
        return None
    else:
        _check_declared(raw, type_name, diags)
        if raw.dialect == BINDING and raw.type_name.value.strip() != type_name:
            diags.warning(
                "ROS427",
                f"{what}: type {raw.type_name.value!r} is written in another spelling (ROS 1 or rosjava)",
                raw.type_name.pointer,
                f"write {type_name!r}, the binding's form",
            )
    component = raw.component.value if raw.component else _default_component(raw.name)
    if type_name is None or type_name.split("/")[1] != kind:
        return None
    # other problems were reported; keep going so type resolution can report its own too
    return _Endpoint(raw, component, ros_name, type_name, errors=not ok)


def _interface_hint(raw: RawEndpoint, kind: str) -> str:
    """ROS421's way out: the binding that fits a `kind` type on this affordance."""
    if raw.kind == "action" and kind == "action":
        return (
            'to bind a ROS action, add "rosv:interface": "action" to the form (the goal is the input, the '
            "result the output)"
        )
    if raw.kind == "action" and kind == "srv":
        return 'to bind a service, remove "rosv:interface": "action" from the form'
    if raw.kind == "action":
        return 'an action binds a service (pkg/srv/Name) or, with "rosv:interface": "action", a pkg/action/Name'
    return f"a {raw.kind} binds a topic: pkg/msg/Name"


def _check_relative_names(endpoints: Sequence[_Endpoint], diags: Diagnostics) -> None:
    """A relative name beside names under the robot namespace is almost always a forgotten placeholder: the
    adaptor's node does not run in the robot's namespace, so every robot of a fleet would share it."""
    if not any(ep.ros_name.namespaced for ep in endpoints):
        return
    for ep in endpoints:
        if not ep.ros_name.namespaced and not ep.ros_name.path.startswith(("/", "~")):
            diags.warning(
                "ROS416",
                f"{ep.raw.kind} {ep.raw.name!r}: ROS name {ep.raw.ros_name.value!r} is relative while the TD's "
                f"other names are under {BINDING_PLACEHOLDER}: every robot of a fleet would share it",
                ep.raw.ros_name.pointer,
                f"write '/{BINDING_PLACEHOLDER}/{ep.ros_name.path}' (or '/{ep.ros_name.path}' if it is global)",
            )


def _default_component(name: str) -> str:
    return (name[:1].upper() + name[1:] + "Component") if name else "Component"


def _check_href(raw: RawEndpoint, ros_name: Any, diags: Diagnostics) -> None:
    href = raw.href
    if href is None:
        return
    if raw.dialect == REFERENCE and href.value == "":
        diags.warning(
            "ROS412",
            f"{raw.kind} {raw.name!r}: empty href and no base (reference-dialect defect)",
            href.pointer,
            "td2adaptor reads the ROS name from the form; 'td2adaptor migrate' writes a ros: href",
        )
    elif raw.dialect == BINDING and isinstance(href.value, str) and href.value.startswith("ros:"):
        expected = "ros:" + ros_name.path
        ref = href.value[4:]
        # a relative href is the name as seen from inside the robot namespace, whether that namespace is
        # still a placeholder or was baked in by instantiating a Thing Model
        baked = not ros_name.namespaced and not ref.startswith("/") and ros_name.path.endswith("/" + ref)
        if href.value != expected and not baked:
            diags.warning(
                "ROS413",
                f"{raw.kind} {raw.name!r}: href {href.value!r} does not match rosv:name",
                href.pointer,
                f"write {expected!r} (the name as seen from inside the robot namespace)",
            )


def _check_declared(raw: RawEndpoint, type_name: str, diags: Diagnostics) -> None:
    """Reference dialect: Java class names are derivable; report any that disagree with the ROS type."""
    pkg, kind, base = type_name.split("/")
    if kind == "srv":
        expected = {
            "ros:serviceRequestType": f"{pkg}.{base}Request",
            "ros:serviceResponseType": f"{pkg}.{base}Response",
        }
    else:
        expected = {"ros:MessageType": f"{pkg}.{base}"}
    for declared in raw.declared:
        key = declared.pointer.rsplit("/", 1)[-1]
        want = expected.get(key)
        if want is not None and declared.value != want:
            diags.warning(
                "ROS422",
                f"{raw.kind} {raw.name!r}: {key} {declared.value!r} does not match {want!r} "
                f"derived from {raw.type_name.value!r}",
                declared.pointer,
                "td2adaptor uses the ROS type; remove the redundant class name or correct it",
            )


def _check_duplicate_names(endpoints: Sequence[_Endpoint], diags: Diagnostics) -> None:
    seen: dict[tuple[str, bool, str], _Endpoint] = {}
    for ep in endpoints:
        space = ep.raw.interface.value
        key = (space, ep.ros_name.namespaced, ep.ros_name.path)
        first = seen.setdefault(key, ep)
        if first is not ep and first.type_name != ep.type_name:
            diags.error(
                "ROS414",
                f"ROS {space} {ep.raw.ros_name.value!r} is bound with type {ep.type_name!r} here and "
                f"{first.type_name!r} by {first.raw.kind} {first.raw.name!r}",
                ep.raw.type_name.pointer,
                "one ROS name has one type",
            )


def _group(endpoints: Sequence[_Endpoint], diags: Diagnostics) -> list[_Group]:
    groups: dict[str, _Group] = {}
    for ep in endpoints:
        g = groups.get(ep.component)
        if g is None:
            ptr = ep.raw.component.pointer if ep.raw.component else ep.raw.pointer
            problem = identifier_problem(ep.component)
            if problem:
                diags.error(
                    "ROS430",
                    f"component name {ep.component!r} {problem}; it becomes a class name",
                    ptr,
                    "use a CamelCase name such as 'GoToComponent'",
                )
            g = groups[ep.component] = _Group(ep.component, ptr)
        g.endpoints.append(ep)
    return list(groups.values())


# ---------------------------------------------------------------------------------------------------------
# procedures


def _procedures(group: _Group, diags: Diagnostics) -> tuple[Procedure, ...]:
    for ep in group.endpoints:
        if ep.raw.interface is Interface.ACTION and ep.raw.procedure is not None:
            diags.error(
                "ROS449",
                f"action {ep.raw.name!r} is bound to a ROS action: rosv:procedure links services into a procedure, "
                "and a ROS action has its own goal states, feedback and cancel, so the procedure would be ignored",
                ep.raw.procedure.pointer,
                "remove rosv:procedure: the edge node follows the goal itself (its query and cancel events: "
                "docs/binding.md)",
            )
    services = {ep.raw.name: ep for ep in group.endpoints if ep.raw.interface is Interface.SERVICE}
    explicit = [ep for ep in services.values() if ep.raw.procedure is not None]
    derived_from_names = all(ep.raw.dialect == REFERENCE for ep in services.values())
    procs: list[Procedure] = []
    claimed: dict[str, str] = {}
    for ep in explicit:
        proc = _explicit_procedure(ep, services, group, claimed, diags)
        if proc is not None:
            procs.append(proc)
    if not explicit and derived_from_names and services:
        proc = _derived_procedure(services, group, diags)
        if proc is not None:
            procs.append(proc)
    for proc in procs:
        services[proc.run].procedure_role = ProcedureRole.RUN
        if proc.query:
            services[proc.query].procedure_role = ProcedureRole.QUERY
        if proc.cancel:
            services[proc.cancel].procedure_role = ProcedureRole.CANCEL
    return tuple(procs)


def _explicit_procedure(
    ep: _Endpoint,
    services: Mapping[str, _Endpoint],
    group: _Group,
    claimed: dict[str, str],
    diags: Diagnostics,
) -> Procedure | None:
    loc = ep.raw.procedure
    assert loc is not None
    value = loc.value
    if not isinstance(value, Mapping):
        diags.error("ROS441", f"action {ep.raw.name!r}: rosv:procedure must be an object", loc.pointer)
        return None
    ok = True
    links: dict[str, str | None] = {"query": None, "cancel": None}
    for key in value:
        if key not in ("query", "cancel", "missionId", *READING_KEYS):
            diags.error(
                "ROS441",
                f"action {ep.raw.name!r}: unknown procedure link {key!r}",
                pointer_join(loc.pointer, key),
                "rosv:procedure has 'query', 'cancel', 'missionId', 'state', 'states' and 'message'",
            )
            ok = False
    for key in ("query", "cancel"):
        target = value.get(key)
        if target is None:
            continue
        tptr = pointer_join(loc.pointer, key)
        if not isinstance(target, str) or target not in services:
            ros_action = any(e.raw.name == target and e.raw.interface is Interface.ACTION for e in group.endpoints)
            diags.error(
                "ROS442",
                f"action {ep.raw.name!r}: procedure {key} {target!r} "
                + (
                    "is bound to a ROS action, not a service"
                    if ros_action
                    else f"is not an action of component {group.name!r}"
                ),
                tptr,
                "name an action bound to a ROS service in the same rosv:component",
            )
            ok = False
        elif target == ep.raw.name:
            diags.error("ROS443", f"action {ep.raw.name!r} cannot be its own {key}", tptr)
            ok = False
        elif target in claimed:
            diags.error(
                "ROS443",
                f"action {target!r} is already linked to procedure {claimed[target]!r}",
                tptr,
                "an action queries or cancels one run action",
            )
            ok = False
        elif services[target].raw.procedure is not None:
            diags.error("ROS443", f"action {target!r} is itself a run action and cannot be its {key}", tptr)
            ok = False
        else:
            links[key] = target
            claimed[target] = ep.raw.name
    mission = value.get("missionId")
    path: tuple[str, ...] = ()
    if mission is not None:
        if isinstance(mission, str) and re.fullmatch(r"[A-Za-z_]\w*(/[A-Za-z_]\w*)*", mission):
            path = tuple(mission.split("/"))
        else:
            diags.error(
                "ROS444",
                f"action {ep.raw.name!r}: missionId must be a '/'-separated response field path",
                pointer_join(loc.pointer, "missionId"),
                "e.g. 'state/header/id'",
            )
            ok = False
    reading = parse_reading(ep.raw.name, value, loc.pointer, diags)
    if reading is None or not ok:
        return None
    state, states, message = reading
    return Procedure(ep.raw.name, links["query"], links["cancel"], path, state, states, message)


def _roles(group: _Group, proc: Procedure) -> dict[str, RoleInfo]:
    """The services a procedure calls, by role, as the state checks need them."""
    by_name = {ep.raw.name: ep for ep in group.endpoints}
    run = by_name[proc.run]
    where = run.raw.procedure.pointer if run.raw.procedure is not None else run.raw.pointer
    out = {}
    for role, name in (("run", proc.run), ("query", proc.query), ("cancel", proc.cancel)):
        if name is not None:
            out[role] = RoleInfo(name, by_name[name].type_name, by_name[name].raw.pointer, where)
    return out


def _role_of(ep: _Endpoint) -> ProcedureRole:
    path = ep.ros_name.path
    for suffixes, role in (
        (_RUN_SUFFIXES, ProcedureRole.RUN),
        (_QUERY_SUFFIXES, ProcedureRole.QUERY),
        (_CANCEL_SUFFIXES, ProcedureRole.CANCEL),
    ):
        if path.endswith(suffixes):
            return role
    for pattern, role in _NAME_ROLE:
        if pattern.search(ep.raw.name):
            return role
    return ProcedureRole.NONE


def _derived_procedure(services: Mapping[str, _Endpoint], group: _Group, diags: Diagnostics) -> Procedure | None:
    """Reference dialect: nothing links xRun to xQuery/xCancel except names (defect 10); derive it."""
    by_role: dict[ProcedureRole, list[str]] = {}
    for name, ep in services.items():
        by_role.setdefault(_role_of(ep), []).append(name)
    runs = by_role.get(ProcedureRole.RUN, [])
    if len(runs) != 1:
        return None
    queries = by_role.get(ProcedureRole.QUERY, [])
    cancels = by_role.get(ProcedureRole.CANCEL, [])
    query = queries[0] if len(queries) == 1 else None
    cancel = cancels[0] if len(cancels) == 1 else None
    if query is None and cancel is None:
        return None
    diags.info(
        "ROS440",
        f"component {group.name!r}: procedure linkage derived from names: run {runs[0]!r}"
        + (f", query {query!r}" if query else "")
        + (f", cancel {cancel!r}" if cancel else ""),
        services[runs[0]].raw.pointer,
        "'td2adaptor migrate' writes it explicitly as rosv:procedure",
    )
    return Procedure(runs[0], query, cancel)


def _mission_ids(
    group: _Group, procs: Sequence[Procedure], tables: Mapping[str, TypeTable], diags: Diagnostics
) -> list[Procedure]:
    """Check explicit mission-id paths; derive `state/header/id` for procedures_msgs-style responses."""
    out = []
    by_name = {ep.raw.name: ep for ep in group.endpoints}
    for proc in procs:
        ep = by_name[proc.run]
        responses = []
        for distro in DISTROS:
            srv = tables[distro].get(ep.type_name)
            if isinstance(srv, ServiceDef):
                responses.append((tables[distro], srv.response))
        if proc.mission_id:
            types = {t.primitive_at(resp, proc.mission_id) for t, resp in responses}
            if responses and not types <= INTEGERS:
                ptr = ep.raw.procedure.pointer if ep.raw.procedure else ep.raw.pointer
                diags.error(
                    "ROS444",
                    f"action {proc.run!r}: missionId {'/'.join(proc.mission_id)!r} is not an integer field "
                    f"of {ep.type_name}'s response",
                    pointer_join(ptr, "missionId"),
                )
            out.append(proc)
            continue
        derived = ("state", "header", "id")
        if responses and all(t.primitive_at(resp, derived) in INTEGERS for t, resp in responses):
            out.append(replace(proc, mission_id=derived))
        else:
            out.append(proc)
    return out


# ---------------------------------------------------------------------------------------------------------
# types


def _registries(
    interface_dirs: Sequence[Path], found: Diagnostics
) -> tuple[dict[str, TypeRegistry], dict[str, list[Diagnostic]]]:
    """Both versions' registries; the interface folders' problems both versions share (and ROS 1's warnings)
    go to `found`, each version's own errors come back beside the registries (see `distros`)."""
    from td2adaptor.rostypes.registry import TypeRegistry

    per = {d: Diagnostics() for d in DISTROS}
    regs = {d: TypeRegistry(d, interface_dirs, per[d]) for d in DISTROS}  # type: ignore[arg-type]
    shared, own = split_problems(per)
    found.extend(shared)
    return regs, own


def _report_interface_problems(
    found: Diagnostics, endpoints: Sequence[_Endpoint], tables: Mapping[str, TypeTable], diags: Diagnostics
) -> None:
    """Problems in interface files: errors where the TD uses the type (or a type that contains it), warnings
    for the rest. An interface folder often holds more than one robot uses, and ROS 1's genmsg builds what
    it can; a broken file nobody needs must not stop the compile. A missing folder stays an error."""
    from td2adaptor.rostypes.names import parse_type_name

    needed: set[tuple[str, str]] = set()
    for name in (
        {ep.type_name for ep in endpoints}
        | {n for table in tables.values() for n in (*table.missing, *(m.name for m in table.messages))}
        | {s.name for table in tables.values() for s in table.services}
    ):
        parsed = parse_type_name(name)
        if parsed is not None:
            needed.add((parsed.package, parsed.name))
    for d in found:
        if d.severity is Severity.ERROR and d.code != "TY500" and not _file_needed(d.file, needed):
            d = replace(d, severity=Severity.WARNING, message=f"{d.message} (the TD uses no type that needs it)")
        diags.append(d)


def _file_needed(file: str | None, needed: set[tuple[str, str]]) -> bool:
    if not file:
        return True
    path = Path(file)
    if path.suffix not in (".msg", ".srv", ".action"):
        return False  # a folder-level problem (e.g. an invalid package name): no TD type can live there
    return (path.parent.parent.name, path.stem) in needed


def _prefixes() -> list[Path]:
    """Where ROS packages are installed here: the sourced prefixes, this Python's (the ros2 extra's wheels
    install into the venv) and /opt/ros/*."""
    found = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [*found, Path(sys.prefix), *sorted(Path("/opt/ros").glob("*"))]


def _where_to_find(type_name: str) -> str:
    """The end of ROS423's hint: the installed package folder that defines `type_name` if there is one, else
    what --interfaces wants (for an action, the action/ folder that is easy to leave out)."""
    parts = type_name.split("/")
    if len(parts) != 3:
        return "add its definition with --interfaces DIR"
    package, kind, name = parts
    for prefix in _prefixes():
        file = prefix / "share" / package / kind / f"{name}.{kind}"
        try:
            if file.is_file():
                return f"{file} defines it: add --interfaces {file.parent.parent}"
        except OSError:  # a prefix we may not read: it defines nothing we could use
            continue
    if kind == "action":
        return f"add its definition with --interfaces DIR, a folder holding {package}/action/{name}.action"
    return "add its definition with --interfaces DIR"


def _resolve_types(
    endpoints: Sequence[_Endpoint],
    regs: Mapping[str, TypeRegistry],
    own: Mapping[str, Sequence[Diagnostic]],
    diags: Diagnostics,
) -> tuple[dict[str, TypeTable], dict[str, TypeTable]]:
    """Per version: the table of the types it can use (with every message they use; the others `missing`,
    with the reason in `unavailable`), and the table of everything the TD names, usable or not (which
    interface files the TD needs)."""
    names = list(dict.fromkeys(ep.type_name for ep in endpoints))
    fits = {d: {n: usable(regs[d], n) for n in names} for d in DISTROS}
    losses: dict[str, dict[str, Loss]] = {d: {} for d in DISTROS}
    reported: set[str] = set()
    for ep in endpoints:
        bad = [d for d in DISTROS if not fits[d][ep.type_name]]
        if not bad or ep.type_name in reported:
            continue
        reported.add(ep.type_name)
        if all(regs[d].resolve(ep.type_name) is None for d in DISTROS):
            close = regs["ros2"].closest(ep.type_name) or regs["ros1"].closest(ep.type_name)
            diags.error(
                "ROS423",
                f"{ep.raw.kind} {ep.raw.name!r}: unknown ROS type {ep.type_name!r}",
                ep.raw.type_name.pointer,
                ("closest known types: " + ", ".join(close) if close else "no similar type is known")
                + "; "
                + _where_to_find(ep.type_name),
            )
            continue
        lost = {d: loss(ep.type_name, d, regs, own[d]) for d in bad}
        what = f"{ep.raw.kind} {ep.raw.name!r}: type {ep.type_name!r}"
        if len(bad) == 1:
            d = bad[0]
            losses[d][ep.type_name] = lost[d]
            diags.warning(
                "ROS424",
                f"{what} is for {LABELS[other(d)]} only: {lost[d].reason}; {BACKENDS[d]} cannot use it",
                ep.raw.type_name.pointer,
                lost[d].hint,
            )
        elif all(found.specific for found in lost.values()):
            diags.error(
                "ROS424",
                f"{what} can be used with neither ROS version: "
                + "; ".join(f"{LABELS[d]}: {lost[d].reason}" for d in DISTROS),
                ep.raw.type_name.pointer,
            )
        # otherwise a problem of the interface files both versions find says why, as an error of its own
    _name_standard_packages(endpoints, regs["ros2"], diags)
    closures = {d: regs[d].table(names) for d in DISTROS}
    tables = {}
    for d in DISTROS:
        table = regs[d].table([n for n in names if fits[d][n]])
        rest = [n for n in names if not fits[d][n]]
        missing = [*table.missing, *rest, *(regs[d].table(rest).missing if rest else ())]
        tables[d] = replace(
            table,
            missing=tuple(dict.fromkeys(missing)),
            unavailable=tuple((n, found.reason) for n, found in losses[d].items()),
        )
    tables["ros1"] = _with_digests(tables["ros1"], regs["ros1"])
    return tables, closures


def _standard_packages(tables: Mapping[str, TypeTable], regs: Mapping[str, TypeRegistry]) -> tuple[str, ...]:
    """Packages of every type the adaptors use that resolves from a standard set in some distro."""
    found: set[str] = set()
    for distro, table in tables.items():
        for name in [*(m.name for m in table.messages), *(s.name for s in table.services)]:
            if regs[distro].is_standard(name):
                found.add(name.split("/")[0])
    return tuple(sorted(found))


def _name_standard_packages(endpoints: Sequence[_Endpoint], reg: TypeRegistry, diags: Diagnostics) -> None:
    """Once per standard interface package the TD binds to: where the robot's software gets it (td2adaptor
    knows its definitions, but the generated adaptor imports it at run time)."""
    from td2adaptor.support.providers import providers

    first: dict[str, _Endpoint] = {}
    for ep in endpoints:
        package = ep.type_name.split("/")[0]
        if package not in first and reg.is_standard(ep.type_name):
            first[package] = ep
    for package, ep in first.items():
        wheel, debian = providers(package)
        diags.info(
            "ROS428",
            f"{package} is a standard interface package: the generated adaptors import it at run time",
            ep.raw.type_name.pointer,
            f"ROS 2: pip install {wheel} (or your ROS 2 distribution's package); ROS 1: apt install {debian}",
        )


def _with_digests(table: TypeTable, reg: TypeRegistry) -> TypeTable:
    """Attach ROS 1 definitions and md5 sums (the rospy and mROS backends put them on the wire)."""
    from dataclasses import replace

    digests = []
    for name in [m.name for m in table.messages] + [s.name for s in table.services]:
        try:
            text, md5 = reg.ros1_definition(name)
        except (KeyError, ValueError):
            continue
        digests.append(Ros1Digest(name, text, md5))
    return replace(table, ros1_digests=tuple(digests))


def _crosscheck(
    endpoints: Sequence[_Endpoint], tables: Mapping[str, TypeTable], diags: Diagnostics, *, ros1_first: bool = False
) -> None:
    """Compare each affordance's data schemas with its message types.

    Schemas may follow ROS 1 or ROS 2 layouts (Header.seq, secs/nsecs vs sec/nanosec); each endpoint is
    checked against every distro its type resolves in, and the distro its schemas fit best is reported. On a
    tie the robot's own ROS wins: ROS 1 for the reference dialect and for a TD naming a ROS 1 master
    (`rosv:masterURI`), else ROS 2.
    """
    from td2adaptor.lowering.crosscheck import crosscheck

    for ep in endpoints:
        raw = ep.raw
        pairs: list[tuple[Any, str, str]] = []
        if raw.interface is not Interface.TOPIC:
            halves = ("_Request", "_Response") if raw.interface is Interface.SERVICE else ("_Goal", "_Result")
            for schema, half, key in (
                (raw.input_schema, halves[0], "input"),
                (raw.output_schema, halves[1], "output"),
            ):
                if isinstance(schema, Mapping):
                    pairs.append((schema, pointer_join(raw.pointer, key), ep.type_name + half))
        elif isinstance(raw.schema, Mapping):
            pairs.append((raw.schema, raw.pointer, ep.type_name))
        if not pairs:
            continue
        best: Diagnostics | None = None
        order = ("ros1", "ros2") if ros1_first or raw.dialect == REFERENCE else ("ros2", "ros1")
        for distro in order:
            if tables[distro].get(ep.type_name) is None:
                continue
            local = Diagnostics()
            for schema, ptr, msg in pairs:
                crosscheck(_plain(schema), ptr, msg, tables[distro], local)
            if best is None or len(local) < len(best):
                best = local
        if best is not None:
            diags.extend(best)


def _plain(value: Any) -> Any:
    from td2adaptor.model import thaw

    return thaw(value)


def _service(ep: _Endpoint, tables: Mapping[str, TypeTable]) -> ServiceEndpoint:
    raw = ep.raw
    return ServiceEndpoint(
        raw.name,
        ep.ros_name,
        ep.type_name,
        raw.text,
        ep.procedure_role,
        raw.input_schema,
        raw.output_schema,
        raw.pointer,
        failure_of(ep.type_name, tables),
    )


def _action(ep: _Endpoint) -> ActionEndpoint:
    raw = ep.raw
    return ActionEndpoint(
        raw.name, ep.ros_name, ep.type_name, raw.text, raw.input_schema, raw.output_schema, raw.pointer
    )


def _topic(ep: _Endpoint) -> TopicEndpoint:
    raw = ep.raw
    role = raw.role if raw.role is not Role.CLIENT else Role.SUBSCRIBER
    return TopicEndpoint(raw.name, ep.ros_name, ep.type_name, role, raw.qos, raw.text, raw.schema, raw.pointer)
