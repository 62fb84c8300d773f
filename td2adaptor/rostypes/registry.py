"""Which ROS interface types exist, and what they contain, for one ROS distribution.

Three layers, later ones overriding earlier ones: the rosbags typestore of the distribution (ROS 1 Noetic or
ROS 2 Jazzy: messages only; `typestore`), the service definitions bundled with td2adaptor (`interfaces/`, for
standard packages such as std_srvs that no typestore has), and the user's interface folders (read by
`parser`). A fourth, `recorded`, only fills gaps: message definitions a recording carries (a bag's connection
texts), used for the types no other layer defines. ROS 1 definition texts and md5 sums come from `md5`.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.model import ActionDef, FieldType, MessageDef, MessageField, ServiceDef, TypeTable
from td2adaptor.rostypes.md5 import Ros1Texts
from td2adaptor.rostypes.names import (
    KINDS,
    Kind,
    is_valid_package_name,
    is_valid_type_name,
    parse_type_name,
    ros1_action_messages,
)
from td2adaptor.rostypes.parser import PART_SUFFIXES, FileParser, ParsedDef, split_sections
from td2adaptor.rostypes.typestore import (
    STORE_NAMES,
    TIME_MESSAGES,
    Distro,
    base_fielddefs,
    base_message,
    base_store,
    store_label,
    to_rosbags,
)

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ["BUNDLED_DIR", "Distro", "Resolved", "TypeRegistry"]

Resolved = MessageDef | ServiceDef | ActionDef

BUNDLED_DIR = Path(__file__).resolve().parent / "interfaces"


# ---------------------------------------------------------------------------------------------------------
# ROS 1 actions


def _genaction(action: str, origin: str) -> list[MessageDef]:
    """The messages genaction derives from ROS 1 action `pkg/action/Name` besides its goal, result and
    feedback: NameActionGoal (header, goal_id, goal), NameActionResult and NameActionFeedback (header, status,
    result/feedback) and NameAction (the three of them), as `pkg/msg/...` (where genpy puts them)."""
    action_msg, action_goal, action_result, action_feedback = ros1_action_messages(action)

    def msg(name: str, *fields: tuple[str, str]) -> MessageDef:
        return MessageDef(name, tuple(MessageField(f, FieldType(t, is_message=True)) for f, t in fields), origin=origin)

    header = ("header", "std_msgs/msg/Header")
    status = ("status", "actionlib_msgs/msg/GoalStatus")
    return [
        msg(action_goal, header, ("goal_id", "actionlib_msgs/msg/GoalID"), ("goal", f"{action}_Goal")),
        msg(action_result, header, status, ("result", f"{action}_Result")),
        msg(action_feedback, header, status, ("feedback", f"{action}_Feedback")),
        msg(
            action_msg,
            ("action_goal", action_goal),
            ("action_result", action_result),
            ("action_feedback", action_feedback),
        ),
    ]


# ---------------------------------------------------------------------------------------------------------
# the registry


#: what genmsg accepts as a type name (rosidl and td2adaptor want CamelCase)
_GENMSG_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


class TypeRegistry:
    """Resolves canonical type names (`pkg/msg/Name`, `pkg/srv/Name`, `pkg/action/Name`) for one distro.

    Services are stored as two messages `pkg/srv/Name_Request` / `_Response`, actions as
    `pkg/action/Name_Goal` / `_Result` / `_Feedback`. Problems in interface folders go to `diags` while the
    registry is built; a definition with errors is left out (and types using it are not reported again).
    """

    def __init__(
        self,
        distro: Distro,
        interface_dirs: Sequence[Path] = (),
        diags: Diagnostics | None = None,
        recorded: Mapping[str, tuple[str, str]] | None = None,
    ) -> None:
        """`recorded`: canonical message name → (where it was recorded, its .msg text), e.g. from a bag."""
        if distro not in STORE_NAMES:
            raise ValueError(f"unknown ROS distribution {distro!r}: expected 'ros1' or 'ros2'")
        self.distro: Distro = distro
        self.diags = diags if diags is not None else Diagnostics()
        self._defs: dict[str, ParsedDef] = {}
        self._services: dict[str, tuple[str, str]] = {}
        self._actions: dict[str, tuple[str, str, str]] = {}
        self._derived: dict[str, MessageDef] = {}  # ROS 1: the genaction messages of the actions above
        self._broken: set[str] = set()
        self._known: tuple[str, ...] | None = None
        self._ros1 = Ros1Texts(self._message, self._written_constants)
        self._typestore: Typestore | None = None
        self._load_dir(BUNDLED_DIR, bundled=True)
        for directory in interface_dirs:
            self._load_dir(Path(directory), bundled=False)
        if recorded:
            self._load_recorded(recorded)
        self._check_references()

    # -- loading ----------------------------------------------------------------------------------------

    def _folder_error(self, code: str, message: str, path: Path, severity: Severity) -> None:
        self.diags.append(Diagnostic(code, severity, message, "", None, str(path)))

    def _load_dir(self, root: Path, *, bundled: bool) -> None:
        if not root.is_dir():
            self._folder_error("TY500", f"interface folder not found: {root}", root, Severity.ERROR)
            return
        if (root / "package.xml").is_file() or any((root / kind).is_dir() for kind in KINDS):
            packages = [root]
        else:
            packages = sorted(p for p in root.iterdir() if p.is_dir() and any((p / k).is_dir() for k in KINDS))
        found = False
        for pkg_dir in packages:
            package = pkg_dir.resolve().name
            if not is_valid_package_name(package):
                self._folder_error(
                    "TY502",
                    f"invalid package name {package!r} (lower-case letters, digits and _, letter first)",
                    pkg_dir,
                    Severity.ERROR,
                )
                found = True
                continue
            for kind in KINDS:
                files = sorted((pkg_dir / kind).glob(f"*.{kind}")) if (pkg_dir / kind).is_dir() else []
                for path in files:
                    found = True
                    self._load_file(path, package, kind, bundled=bundled)
        if not found:
            self._folder_error(
                "TY501",
                f"no <pkg>/msg/*.msg, <pkg>/srv/*.srv or <pkg>/action/*.action files under {root}",
                root,
                Severity.WARNING,
            )

    def _load_file(self, path: Path, package: str, kind: Kind, *, bundled: bool) -> None:
        origin = f"td2adaptor:{path.relative_to(BUNDLED_DIR).as_posix()}" if bundled else None
        parser = FileParser(path, package, self.distro, self.diags, origin)
        stem = path.name[: -len(kind) - 1]
        if not is_valid_type_name(stem):
            if self.distro == "ros1" and _GENMSG_NAME.fullmatch(stem):
                parser.report(
                    "TY517",
                    f"type name {stem!r} is accepted by ROS 1 (genmsg) but not by ROS 2 or td2adaptor, which need "
                    "CamelCase letters and digits: skipped, a TD cannot use it",
                    severity=Severity.WARNING,
                )
                return
            parser.report("TY502", f"invalid type name {stem!r} (CamelCase letters and digits)")
            return
        name = f"{package}/{kind}/{stem}"
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            parser.report("TY503", f"cannot read {path}: {exc}")
            self._broken.add(name)
            return
        sections, separators, loose = split_sections(text, genmsg=self.distro == "ros1")
        for loose_line in loose:
            parser.report(
                "TY517",
                "a separator other than '---' alone is accepted by ROS 1 (genmsg) but not by ROS 2 (rosidl)",
                loose_line,
                hint="write the separator as '---'",
                severity=Severity.WARNING,
            )
        suffixes = PART_SUFFIXES[kind]
        if len(sections) != len(suffixes):
            line = separators[len(suffixes) - 1] if len(separators) >= len(suffixes) else None
            parser.report(
                "TY514",
                f"a .{kind} file needs {len(suffixes) - 1} '---' separator line(s), found {len(separators)}",
                line,
            )
            self._broken.add(name)
            return
        defs = [parser.section(f"{name}{suffix}", lines) for suffix, lines in zip(suffixes, sections, strict=True)]
        if not parser.ok:
            self._broken.update([name, *(d.msg.name for d in defs)])
            return
        self._warn_if_replacing(name, defs, parser, bundled)
        for d in defs:
            self._defs[d.msg.name] = d
            self._broken.discard(d.msg.name)
        self._broken.discard(name)
        if kind == "srv":
            self._services[name] = (defs[0].msg.name, defs[1].msg.name)
        elif kind == "action":
            self._actions[name] = (defs[0].msg.name, defs[1].msg.name, defs[2].msg.name)
            if self.distro == "ros1":
                self._derived.update((m.name, m) for m in _genaction(name, path.as_posix()))

    def _load_recorded(self, recorded: Mapping[str, tuple[str, str]]) -> None:
        """The recorded definitions of the types no other layer has. A recording is not the user's file: one
        that does not parse here (a ROS 2 bounded type in a ROS 1 registry, say), or uses a type nobody
        defines, is left out quietly, and its topics get no schema (the caller says so)."""
        added: list[str] = []
        for name, (where, text) in recorded.items():
            pieces = name.split("/")
            if len(pieces) != 3 or pieces[1] != "msg" or name in self._defs or self._message(name) is not None:
                continue
            scratch = Diagnostics()
            parser = FileParser(Path(where), pieces[0], self.distro, scratch, f"recorded:{where}")
            sections, _, _ = split_sections(text, genmsg=self.distro == "ros1")
            if len(sections) != 1:
                continue
            parsed = parser.section(name, sections[0])
            if parser.ok and not scratch.has_errors:
                self._defs[name] = parsed
                added.append(name)
        changed = True
        while changed:  # drop those using a type that does not resolve (or a dropped one)
            changed = False
            for name in added:
                if name in self._defs and not all(
                    self._message(f.type.base) is not None for f in self._defs[name].msg.fields if f.type.is_message
                ):
                    del self._defs[name]
                    changed = True

    def _warn_if_replacing(self, name: str, defs: Sequence[ParsedDef], parser: FileParser, bundled: bool) -> None:
        """Overriding is allowed, but a silently different definition would change behaviour and md5s."""
        for d in defs:
            earlier = self._defs.get(d.msg.name)
            if earlier is not None:
                if earlier.msg != d.msg:
                    parser.report(
                        "TY531",
                        f"{name} replaces a different definition from {earlier.file}",
                        severity=Severity.WARNING,
                    )
                    return
                continue
            if bundled:
                continue
            base = base_message(self.distro, d.msg.name)
            if base is not None and base != d.msg:
                store = store_label(self.distro)
                parser.report(
                    "TY530",
                    f"{name} replaces the different {store} definition of the same name",
                    hint="rename the type if it is not meant to be the standard one",
                    severity=Severity.WARNING,
                )
                return

    def _check_references(self) -> None:
        """Every message type used in an interface file must exist, and no message may contain itself."""
        for name, d in self._defs.items():
            if name in self._broken:
                continue
            for fld, line in zip(d.msg.fields, d.field_lines, strict=True):
                target = fld.type.base
                if not fld.type.is_message or target in self._broken or self._message(target) is not None:
                    continue
                similar = self.closest(target)
                self.diags.append(
                    Diagnostic(
                        "TY520",
                        Severity.ERROR,
                        f"field {fld.name!r} of {name} uses undefined type {target}",
                        "",
                        f"did you mean {', '.join(similar)}?" if similar else "add its definition",
                        d.file,
                        line,
                    )
                )
        self._check_cycles()
        self._known = None

    def _check_cycles(self) -> None:
        state: dict[str, int] = {}  # 1 = on the DFS stack, 2 = done

        def visit(name: str, path: list[str]) -> None:
            state[name] = 1
            msg = self._message(name)
            for fld in msg.fields if msg is not None else ():
                target = fld.type.base
                if not fld.type.is_message:
                    continue
                if state.get(target) == 1:
                    self._report_cycle(path[path.index(target) :])
                elif target not in state:
                    visit(target, [*path, target])
            state[name] = 2

        for name in list(self._defs):
            if name not in state and name not in self._broken:
                visit(name, [name])

    def _report_cycle(self, cycle: list[str]) -> None:
        user = [n for n in cycle if n in self._defs and n not in self._broken]
        if not user:
            return
        first = self._defs[user[0]]
        self.diags.append(
            Diagnostic(
                "TY521",
                Severity.ERROR,
                f"recursive message definition: {' -> '.join([*cycle, cycle[0]])}",
                "",
                "a message cannot contain itself, not even through other messages",
                first.file,
                first.field_lines[0] if first.field_lines else None,
            )
        )
        self._broken.update(user)

    # -- lookup -----------------------------------------------------------------------------------------

    def _message(self, name: str) -> MessageDef | None:
        if name in self._broken:
            return None
        found = self._defs.get(name)
        if found is not None:
            return found.msg
        derived = self._derived.get(name)
        if derived is not None:
            return derived
        return base_message(self.distro, name) or self._base_action_part(name)

    def _base_action_part(self, name: str) -> MessageDef | None:
        """ROS 1: `pkg/action/Name_Goal` (Result, Feedback) of an action the typestore knows only by its
        genaction messages (`pkg/msg/NameGoal`, `pkg/msg/NameActionGoal`, ...), under its canonical name."""
        pieces = name.split("/")
        if self.distro != "ros1" or len(pieces) != 3 or pieces[1] != "action":
            return None
        stem, _, part = pieces[2].rpartition("_")
        if part not in ("Goal", "Result", "Feedback") or base_message("ros1", f"{pieces[0]}/msg/{stem}Action") is None:
            return None
        found = base_message("ros1", f"{pieces[0]}/msg/{stem}{part}")
        return None if found is None else MessageDef(name, found.fields, found.constants, found.origin)

    def _base_action(self, name: str) -> tuple[str, str, str] | None:
        """ROS 1: the parts of `pkg/action/Name` when only the typestore knows it (see `_base_action_part`)."""
        if self.distro != "ros1" or "/action/" not in name or name in self._actions:
            return None
        parts = (f"{name}_Goal", f"{name}_Result", f"{name}_Feedback")
        return parts if all(self._base_action_part(p) is not None for p in parts) else None

    def _written_constants(self, name: str) -> tuple[str, ...] | None:
        """Constant values as written in an interface file (genmsg hashes the text); None for typestore types."""
        found = self._defs.get(name)
        return found.const_texts if found is not None else None

    def resolve(self, name: str) -> Resolved | None:
        """The definition of a canonical name (message, service, action or one of their parts), or None."""
        if name in self._broken:
            return None
        if name in self._services:
            req, resp = (self._message(n) for n in self._services[name])
            return ServiceDef(name, req, resp) if req is not None and resp is not None else None
        parts = self._actions.get(name) or self._base_action(name)
        if parts is not None:
            goal, result, feedback = (self._message(n) for n in parts)
            if goal is None or result is None or feedback is None:
                return None
            return ActionDef(name, goal, result, feedback)
        return self._message(name)

    def is_standard(self, name: str) -> bool:
        """Whether `name` resolves from a standard interface package (rosbags' type sets, or the definitions
        td2adaptor bundles) rather than from the user's --interfaces: the robot's software must install it."""
        part = (
            self._services[name][0]
            if name in self._services
            else self._actions[name][0]
            if name in self._actions
            else name
        )
        found = self._defs.get(part)
        if found is None:
            return self._message(part) is not None
        return Path(found.file).is_relative_to(BUNDLED_DIR)

    def known_names(self, kind: Kind | None = None) -> list[str]:
        """Sorted canonical names of all messages, services and actions (not their parts)."""
        if self._known is None:
            names: set[str] = set(self._services) | set(self._actions)
            names.update(n for n in self._defs if "/msg/" in n)
            names.update(self._derived)
            names.update(n for n in base_fielddefs(self.distro) if "/msg/" in n)
            if self.distro == "ros1":  # actions the typestore has as genaction messages
                stems = {n[: -len("ActionGoal")] for n in names if n.endswith("ActionGoal") and "/msg/" in n}
                names.update(a for s in stems if self._base_action(a := s.replace("/msg/", "/action/")))
            if self.distro == "ros1":
                names.difference_update(TIME_MESSAGES)
            names.difference_update(self._broken)
            self._known = tuple(sorted(names))
        if kind is None:
            return list(self._known)
        return [n for n in self._known if f"/{kind}/" in n]

    def closest(self, name: str, n: int = 3) -> list[str]:
        """Known names resembling `name`, best first: same type name in another package, then by spelling."""
        parsed = parse_type_name(name)
        query = parsed.canonical if parsed is not None else name.strip()
        known = self.known_names()
        short = re.split(r"[/.]", query)[-1].lower()
        out = sorted((k for k in known if k.rsplit("/", 1)[-1].lower() == short), key=lambda k: (k != query, k))
        lowered = {k.lower(): k for k in known}
        out += [lowered[m] for m in difflib.get_close_matches(query.lower(), list(lowered), n=n, cutoff=0.6)]
        return list(dict.fromkeys(out))[:n]

    def table(self, names: Sequence[str]) -> TypeTable:
        """The named types plus every message they use, in depth-first first-use order; unknowns → missing."""
        messages: dict[str, MessageDef] = {}
        services: dict[str, ServiceDef] = {}
        actions: dict[str, ActionDef] = {}
        missing: dict[str, None] = {}

        def visit(msg: MessageDef) -> None:
            for fld in msg.fields:
                if not fld.type.is_message or fld.type.base in messages:
                    continue
                sub = self._message(fld.type.base)
                if sub is None:
                    missing[fld.type.base] = None
                else:
                    messages[sub.name] = sub
                    visit(sub)

        for name in names:
            if name in messages or name in services or name in actions:
                continue
            found = self.resolve(name)
            if found is None:
                missing[name] = None
            elif isinstance(found, ServiceDef):
                services[name] = found
                visit(found.request)
                visit(found.response)
            elif isinstance(found, ActionDef):
                actions[name] = found
                for part in (found.goal, found.result, found.feedback):
                    visit(part)
            else:
                messages[name] = found
                visit(found)
        return TypeTable(
            self.distro,
            tuple(messages.values()),
            tuple(services.values()),
            tuple(actions.values()),
            tuple(missing),
        )

    # -- ROS 1 definitions and md5 sums -----------------------------------------------------------------

    def ros1_definition(self, name: str) -> tuple[str, str]:
        """ROS 1 full definition text and md5 sum of a message or service (ros1 registries only); an action's
        goal/result/feedback go by `pkg/action/Name_Goal`..., its genaction messages by `pkg/msg/NameAction`...

        Messages: the text rospy/rosbag put in connection headers (the message, then each message it uses
        after a `====...` line and `MSG: pkg/Name`). Services: request and response texts around `---`, and
        genpy's service md5 (one md5 over the request and response md5 texts). KeyError for unknown types or
        types using unknown types.
        """
        if self.distro != "ros1":
            raise ValueError("ROS 1 definitions need a ros1 registry")
        if name in self._services and name not in self._broken:
            return self._ros1.service(*self._services[name])
        return self._ros1.message(name)

    # -- rosbags typestore with the user's types --------------------------------------------------------

    def typestore(self) -> Typestore:
        """A rosbags typestore of this distro plus every complete user/bundled type (for serialisation).

        Built on first use (it generates code); the per-process base typestore itself stays untouched.
        """
        if self._typestore is None:
            from rosbags.typesys.store import Typestore as RosbagsTypestore

            base = base_store(self.distro)
            store = RosbagsTypestore()
            store.fielddefs.update(base.fielddefs)
            store.types.update(base.types)
            usable = [n for n in self._defs if self._complete(n)]
            for name in usable:
                store.fielddefs.pop(name, None)
                store.types.pop(name, None)
            if usable:
                typs = {name: to_rosbags(self._defs[name].msg) for name in usable}
                store.register(cast(Any, typs))
            self._typestore = store
        return self._typestore

    def _complete(self, name: str, seen: set[str] | None = None) -> bool:
        """Whether `name` and everything it uses resolves."""
        seen = set() if seen is None else seen
        if name in seen:
            return True
        seen.add(name)
        msg = self._message(name)
        if msg is None:
            return False
        return all(self._complete(f.type.base, seen) for f in msg.fields if f.type.is_message)
