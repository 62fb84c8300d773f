"""Can the edge node follow a procedure? How it reads a state from a response, and how the mission id travels.

A procedure's state comes either from the binding (`rosv:procedure` `state`: a response field path, `states`:
its values → queued/running/paused/finished/failed/cancelled, `message`: a field path), or, by default, from
the procedures_msgs convention (`state/current_state`, ...). The edge node follows a mission by querying it,
so a linked query whose response carries no state is an error (ROS445): at run time every answer would read
as a failure while the robot works. A mapping that names no field, or values no state, is an error (ROS446).
A mission id the query/cancel requests cannot carry is a warning (ROS447): the node then asks about the
robot's current procedure. A procedure without a query (and no state in its run response) is a warning
(ROS448): its invoke can only report that the robot took the run.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from td2adaptor.diagnostics import Diagnostics, pointer_join
from td2adaptor.model import Failure, Procedure, ServiceDef, TypeTable
from td2adaptor.model.primitives import INTEGERS

READING_KEYS = ("state", "states", "message")
#: the states a mapping may name (what feedback and state events report)
MAPPED_STATES = ("queued", "running", "paused", "finished", "failed", "cancelled")
_PATH = re.compile(r"[A-Za-z_]\w*(/[A-Za-z_]\w*)*")
#: types whose values read as decimal integers
_WHOLE = INTEGERS | {"byte", "char"}
_CONVENTION = ("state", "current_state")


@dataclass(frozen=True)
class RoleInfo:
    """One service of a procedure: its affordance, type, pointer, and the pointer of the rosv:procedure."""

    action: str
    type_name: str
    pointer: str
    procedure_pointer: str


def parse_reading(
    action: str, value: Mapping[str, Any], pointer: str, diags: Diagnostics
) -> tuple[tuple[str, ...], tuple[tuple[str, str], ...], tuple[str, ...]] | None:
    """`state`, `states` and `message` of a rosv:procedure object; None (after ROS446) when malformed."""
    ok = True

    def path(key: str) -> tuple[str, ...]:
        nonlocal ok
        raw = value.get(key)
        if raw is None:
            return ()
        if isinstance(raw, str) and _PATH.fullmatch(raw):
            return tuple(raw.split("/"))
        diags.error(
            "ROS446",
            f"action {action!r}: procedure {key} must be a '/'-separated response field path",
            pointer_join(pointer, key),
            "e.g. 'status/state'",
        )
        ok = False
        return ()

    state, message = path("state"), path("message")
    states: list[tuple[str, str]] = []
    raw = value.get("states")
    if raw is not None:
        if not isinstance(raw, Mapping) or not raw:
            diags.error(
                "ROS446",
                f"action {action!r}: procedure states must be an object mapping field values to states",
                pointer_join(pointer, "states"),
                'e.g. {"0": "queued", "1": "running", "2": "finished", "3": "failed", "4": "cancelled"}',
            )
            return None
        for key, target in raw.items():
            if target not in MAPPED_STATES:
                diags.error(
                    "ROS446",
                    f"action {action!r}: procedure state value {key!r} maps to {target!r}, which is not a state",
                    pointer_join(pointer_join(pointer, "states"), str(key)),
                    "map each value to one of " + ", ".join(MAPPED_STATES),
                )
                ok = False
            else:
                states.append((str(key), str(target)))
    if bool(state) != bool(raw is not None):
        given, missing = ("state", "states") if state else ("states", "state")
        diags.error(
            "ROS446",
            f"action {action!r}: procedure {given} without {missing}",
            pointer_join(pointer, given),
            "'state' names the response field, 'states' maps its values: give both (or neither, for the "
            "procedures_msgs convention)",
        )
        ok = False
    if message and not state:
        diags.error(
            "ROS446",
            f"action {action!r}: procedure message without state",
            pointer_join(pointer, "message"),
            "'message' is read beside a mapped 'state'",
        )
        ok = False
    return (state, tuple(states), message) if ok else None


def _services(info: RoleInfo, tables: Mapping[str, TypeTable]) -> list[tuple[TypeTable, ServiceDef]]:
    out = []
    for table in tables.values():
        found = table.get(info.type_name)
        if isinstance(found, ServiceDef):
            out.append((table, found))
    return out


def _has(info: RoleInfo, tables: Mapping[str, TypeTable], path: Sequence[str], *, request: bool = False) -> bool:
    """Whether every resolved definition of the service has a primitive field at `path`."""
    found = _services(info, tables)
    return bool(found) and all(
        table.primitive_at(srv.request if request else srv.response, path) is not None for table, srv in found
    )


def mission_slot(info: RoleInfo, tables: Mapping[str, TypeTable], id_path: Sequence[str]) -> tuple[str, ...]:
    """Where the request carries a mission id, the one rule both Python backends and the edge node read (as
    `Procedure.slot`): an integer field at the longest suffix of the run response's id path (`header/id` for
    `state/header/id`), else at header/id, id or mission_id, in every ROS version that defines the type; ()
    when there is none."""
    candidates = [tuple(id_path[i:]) for i in range(len(id_path))] + [("header", "id"), ("id",), ("mission_id",)]
    found = _services(info, tables)
    for path in candidates if found else ():
        if all(table.primitive_at(srv.request, path) in INTEGERS for table, srv in found):
            return path
    return ()


def failure_of(type_name: str, tables: Mapping[str, TypeTable]) -> Failure:
    """How the response of service `type_name` says the robot failed (`Failure`), when every ROS version that
    defines the type agrees; NONE when it cannot say (or the versions differ)."""
    styles = set()
    for table in tables.values():
        srv = table.get(type_name)
        if not isinstance(srv, ServiceDef):
            continue
        response = srv.response
        if (
            table.primitive_at(response, ("result", "result"))
            == "string"
            == table.primitive_at(response, ("result", "message"))
        ):
            styles.add(Failure.RESULT)
        elif table.primitive_at(response, ("success",)) == "bool":
            has_message = table.primitive_at(response, ("message",)) == "string"
            styles.add(Failure.SUCCESS if has_message else Failure.SUCCESS_ONLY)
        else:
            styles.add(Failure.NONE)
    return styles.pop() if len(styles) == 1 else Failure.NONE


def check_reading(
    proc: Procedure, roles: Mapping[str, RoleInfo], tables: Mapping[str, TypeTable], diags: Diagnostics
) -> Procedure:
    """`proc` with the roles whose responses carry a state (`stateful`), after reporting what the edge node
    could not follow (see the module docstring)."""
    run = roles["run"]
    path = proc.state or _CONVENTION
    stateful = frozenset(role for role, info in roles.items() if _has(info, tables, path))
    resolved = {role for role, info in roles.items() if _services(info, tables)}
    if proc.state:
        _check_values(proc, roles, tables, diags)
    query = roles.get("query")
    if query is not None and "query" in resolved and "query" not in stateful:
        how = f"has no field {'/'.join(proc.state)}" if proc.state else "has no state/current_state"
        diags.error(
            "ROS445",
            f"procedure {proc.run!r}: the response of its query {query.action!r} ({query.type_name}) {how}: the "
            "edge node could not tell whether a mission runs, ended or failed",
            query.procedure_pointer,
            'name the response field that holds the state in rosv:procedure: "state": "<field/path>" and '
            '"states": {"<value>": "running", ...} (docs/binding.md), or link a query whose response has one',
        )
    elif proc.state and "query" not in roles and "run" not in stateful and "run" in resolved:
        diags.error(
            "ROS445",
            f"procedure {proc.run!r}: its run response ({run.type_name}) has no field {'/'.join(proc.state)}",
            pointer_join(run.procedure_pointer, "state"),
        )
    elif "query" not in roles and "run" not in stateful and "run" in resolved:
        diags.warning(
            "ROS448",
            f"procedure {proc.run!r} has no query: the edge node can report only that the robot took the run "
            "(its invoke ends 'finished' with the message 'started'), not when or how the mission ends",
            run.procedure_pointer,
            "link a query action whose response carries the state (rosv:procedure query), or map a state field "
            "of the run response with state/states",
        )
    slots: list[tuple[str, tuple[str, ...]]] = []
    for role in ("query", "cancel"):
        info = roles.get(role)
        if info is None or role not in resolved:
            continue
        if not proc.mission_id:
            diags.warning(
                "ROS447",
                f"procedure {proc.run!r}: the run response ({run.type_name}) carries no mission id, so its {role} "
                f"{info.action!r} cannot name the mission: the edge node asks about the robot's current one",
                run.procedure_pointer,
                "name the run response's integer id field with missionId, if the robot has one",
            )
            break
        slot = mission_slot(info, tables, proc.mission_id)
        if slot:
            slots.append((role, slot))
        else:
            diags.warning(
                "ROS447",
                f"procedure {proc.run!r}: the request of its {role} {info.action!r} ({info.type_name}) has no "
                f"integer field for the mission id: the edge node asks about the robot's current mission",
                info.pointer,
                "a request field at the end of the missionId path (or header/id, id, mission_id) carries the id",
            )
    return replace(proc, stateful=stateful, slots=tuple(slots))


def _check_values(
    proc: Procedure, roles: Mapping[str, RoleInfo], tables: Mapping[str, TypeTable], diags: Diagnostics
) -> None:
    """The mapped values must be spellable values of the state field (numbers for a numeric field)."""
    info = roles.get("query", roles["run"])
    kinds = {table.primitive_at(srv.response, proc.state) for table, srv in _services(info, tables)} - {None}
    if proc.message and _services(info, tables) and not _has(info, tables, proc.message):
        diags.error(
            "ROS446",
            f"procedure {proc.run!r}: the response of {info.action!r} ({info.type_name}) has no field "
            f"{'/'.join(proc.message)} for the message",
            pointer_join(info.procedure_pointer, "message"),
        )
    for key, _ in proc.states:
        for kind in kinds:
            if kind in _WHOLE and not re.fullmatch(r"-?\d+", key):
                bad = "an integer"
            elif kind == "bool" and key not in ("true", "false"):
                bad = "true or false"
            else:
                continue
            diags.error(
                "ROS446",
                f"procedure {proc.run!r}: state value {key!r} can never be read from {'/'.join(proc.state)}, "
                f"a {kind} field",
                pointer_join(pointer_join(info.procedure_pointer, "states"), key),
                f"write the value as {bad}",
            )
            break
