"""Which ROS version can use each type a TD binds, and why the other cannot.

An interface folder written for one ROS version often does not build for the other: Nav2's actions use
`builtin_interfaces/Duration`, which ROS 1 does not define; a ROS 2 bounded string is no ROS 1 type; a ROS 1
message may use `std_msgs/Duration`, which ROS 2 dropped. Each version's registry reads the folders on its
own. A problem both versions find is a problem of the folder (reported as it always was); an error only one
version finds, and a type only one version defines, make the types that need them that version's loss: the
TD stays valid for the other version, and ROS424 says once per bound type why the one cannot use it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.model import ActionDef, MessageDef, ServiceDef

if TYPE_CHECKING:
    from td2adaptor.rostypes.registry import TypeRegistry

DISTROS = ("ros1", "ros2")
LABELS = {"ros1": "ROS 1", "ros2": "ROS 2"}
#: the backends each version's types feed (ROS424's message names them)
BACKENDS = {"ros1": "the rospy and mROS backends", "ros2": "the rclpy backend"}
#: ROS 2 messages ROS 1 writes as primitives: a ROS 1 copy of a file using them builds for both versions
_ROS1_SPELLING = {"builtin_interfaces/msg/Duration": "duration", "builtin_interfaces/msg/Time": "time"}


def other(distro: str) -> str:
    return "ros2" if distro == "ros1" else "ros1"


def _key(d: Diagnostic) -> tuple[object, ...]:
    return (d.code, d.severity, d.message, d.file, d.line, d.col)


def split_problems(found: Mapping[str, Diagnostics]) -> tuple[list[Diagnostic], dict[str, list[Diagnostic]]]:
    """The interface folders' problems as each version's registry reported them → (what to report as the
    folders' own: every problem ROS 1 found but the errors only ROS 1 found; each version's own errors).

    ROS 1's warnings are reported as before (TY517: a name only genmsg accepts, TY515: a default ROS 1
    ignores); ROS 2's own warnings were never reported and are not now."""
    keys = {distro: {_key(d) for d in found[distro]} for distro in DISTROS}
    own = {
        distro: [d for d in found[distro] if d.severity is Severity.ERROR and _key(d) not in keys[other(distro)]]
        for distro in DISTROS
    }
    shared = [d for d in found["ros1"] if d.severity is not Severity.ERROR or _key(d) in keys["ros2"]]
    return shared, own


@dataclass(frozen=True)
class Loss:
    """Why one version cannot use a type: `reason` is a clause for a message; `specific` when the cause is
    something the other version has (a type only it defines, an error only this version finds), not a
    problem of the folder both versions share (that one is reported as an error of its own)."""

    reason: str
    specific: bool
    hint: str | None = None


def usable(reg: TypeRegistry, name: str) -> bool:
    """Whether `name` resolves in `reg` with every message it uses."""
    return reg.resolve(name) is not None and not reg.table([name]).missing


def loss(name: str, distro: str, regs: Mapping[str, TypeRegistry], own: Sequence[Diagnostic]) -> Loss:
    """Why `distro` cannot use `name` (which `usable` said of it); `own`: that version's own errors."""
    reg, theirs, label = regs[distro], regs[other(distro)], LABELS[distro]
    if reg.resolve(name) is None:
        problem = _problem_of(name, own)
        if problem is not None:
            return Loss(f"{label} cannot read its definition: {_said(problem)}", True)
        return Loss(f"{label} does not define it", theirs.resolve(name) is not None)
    gap = first_gap(reg, name)
    if gap is None:  # `usable` said no: a part of a service or action that does not resolve
        return Loss(f"{label} cannot resolve all of it", False)
    owner, field_name, used = gap
    where = f"field {field_name!r} of {owner} is a {used}"
    problem = _problem_of(used, own)
    if problem is not None:
        return Loss(f"{where}, whose definition {label} cannot read: {_said(problem)}", True)
    spelled = _ROS1_SPELLING.get(used) if distro == "ros1" else None
    hint = (
        f"ROS 1 writes {used} as the primitive `{spelled}`, which the ROS 2 build turns into {used}: an interface "
        f"file written with `{spelled}` builds for both"
        if spelled
        else None
    )
    return Loss(f"{where}, which {label} does not define", theirs.resolve(used) is not None, hint)


def first_gap(reg: TypeRegistry, name: str) -> tuple[str, str, str] | None:
    """(message, field, type) of the first field under `name` whose message type `reg` cannot resolve."""
    found = reg.resolve(name)
    if isinstance(found, ServiceDef):
        roots: list[MessageDef] = [found.request, found.response]
    elif isinstance(found, ActionDef):
        roots = [found.goal, found.result, found.feedback]
    else:
        roots = [found] if found is not None else []
    seen: set[str] = set()

    def visit(msg: MessageDef) -> tuple[str, str, str] | None:
        seen.add(msg.name)
        for fld in msg.fields:
            if not fld.type.is_message or fld.type.base in seen:
                continue
            sub = reg.resolve(fld.type.base)
            if not isinstance(sub, MessageDef):
                return (msg.name, fld.name, fld.type.base)
            gap = visit(sub)
            if gap is not None:
                return gap
        return None

    for root in roots:
        gap = visit(root)
        if gap is not None:
            return gap
    return None


def _problem_of(name: str, own: Sequence[Diagnostic]) -> Diagnostic | None:
    """The first of `own` in the file that defines `name` (`pkg/kind/Name` or a part `pkg/kind/Name_Goal`)."""
    pieces = name.split("/")
    if len(pieces) != 3:
        return None
    package, kind, stem = pieces[0], pieces[1], pieces[2]
    for d in own:
        path = Path(d.file or "")
        if path.suffix != f".{kind}" or path.parent.parent.name != package:
            continue
        if stem == path.stem or stem.startswith(path.stem + "_"):
            return d
    return None


def _said(d: Diagnostic) -> str:
    """A problem one version found, as a clause: its message and where."""
    return f"{d.message} ({d.location})"
