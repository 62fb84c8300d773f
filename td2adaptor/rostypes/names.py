"""ROS interface type names: the spellings TDs use, and the canonical `pkg/{msg,srv,action}/Name` form.

TDs name types the ROS 1 way (`pkg/Name`), the ROS 2 way (`pkg/msg/Name`) or as rosjava class names
(`pkg.Name`, `pkg.NameRequest`). Everything downstream works on one canonical spelling, so the spelling is
settled here, once, and malformed names are rejected instead of guessed at.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

Kind = Literal["msg", "srv", "action"]
Part = Literal["request", "response", "goal", "result", "feedback"]

KINDS: tuple[Kind, ...] = ("msg", "srv", "action")

# Suffixes of the messages that make up services and actions (ROS 2 convention, also used for ROS 1 here).
SERVICE_PARTS: dict[Part, str] = {"request": "_Request", "response": "_Response"}
ACTION_PARTS: dict[Part, str] = {"goal": "_Goal", "result": "_Result", "feedback": "_Feedback"}

_PACKAGE_RE = re.compile(r"[a-z][a-z0-9_]*")
_TYPE_RE = re.compile(r"[A-Z][A-Za-z0-9]*")
# rosjava/genpy name the halves of service `Name` as `NameRequest` / `NameResponse`.
_LEGACY_HALF_RE = re.compile(r"(?P<base>[A-Z][A-Za-z0-9]*?)(?P<half>Request|Response)")


def is_valid_package_name(name: str) -> bool:
    """ROS package names: lower-case letters, digits and underscores, starting with a letter."""
    return _PACKAGE_RE.fullmatch(name) is not None


def is_valid_type_name(name: str) -> bool:
    """ROS interface type names: CamelCase letters and digits, starting with an upper-case letter."""
    return _TYPE_RE.fullmatch(name) is not None


#: the longest file or folder name Linux, macOS and Windows file systems accept, in bytes
NAME_MAX = 255


def file_name_problem(type_name: str) -> str | None:
    """Why canonical `pkg/kind/Name` cannot name an interface file (`pkg/kind/Name.kind`): a name longer than
    file systems allow could never have a definition; None when it can."""
    package, kind, name = type_name.split("/")
    if len(package.encode()) > NAME_MAX:
        return f"its package name has {len(package)} characters; a package is a folder, at most {NAME_MAX}"
    if len(f"{name}.{kind}".encode()) > NAME_MAX:
        return (
            f"its file {name[:12]}….{kind} would have a name of {len(name) + len(kind) + 1} characters; "
            f"file systems allow at most {NAME_MAX}"
        )
    return None


@dataclass(frozen=True)
class TypeName:
    """A parsed type name: `package/kind/name`, and which part of a service/action it named, if any."""

    package: str
    kind: Kind
    name: str
    part: Part | None = None

    @property
    def canonical(self) -> str:
        """The interface itself: `pkg/srv/Name` even when the input named one half of it."""
        return f"{self.package}/{self.kind}/{self.name}"

    @property
    def message_name(self) -> str:
        """The message the input denoted: a part's `pkg/srv/Name_Request`, else the canonical name."""
        if self.part is None:
            return self.canonical
        suffix = SERVICE_PARTS.get(self.part) or ACTION_PARTS[self.part]
        return f"{self.canonical}{suffix}"


def _split_part(kind: Kind, base: str) -> tuple[str, Part | None]:
    """Strip a `_Request`/`_Goal`/... suffix from a canonical srv/action base name."""
    parts = SERVICE_PARTS if kind == "srv" else ACTION_PARTS if kind == "action" else {}
    for part, suffix in parts.items():
        if base.endswith(suffix):
            return base[: -len(suffix)], part
    return base, None


def _make(package: str, kind: Kind, name: str, part: Part | None = None) -> TypeName | None:
    if not (is_valid_package_name(package) and is_valid_type_name(name)):
        return None
    return TypeName(package, kind, name, part)


def parse_type_name(raw: str, kind: Kind | None = None) -> TypeName | None:
    """Parse any spelling a TD may use; `kind` decides the forms that do not say it (default: msg).

    * `pkg/msg/Name`, `pkg/srv/Name`, `pkg/action/Name`: already canonical; `kind` is not consulted, so the
      caller can tell a message given where a service was expected. `pkg/srv/Name_Request` and the like name
      one part of the interface.
    * `pkg/Name` (ROS 1) and `pkg.Name` (rosjava): `pkg/<kind>/Name`.
    * `pkg.NameRequest` / `pkg.NameResponse` (rosjava) with kind srv or None, and `pkg/NameRequest` (genpy)
      with kind srv: one half of service `pkg/srv/Name`. With kind msg they stay messages, since messages
      such as `moveit_msgs/MotionPlanRequest` exist.

    Returns None for anything malformed (wrong separators, bad package or type name, empty parts).
    """
    text = raw.strip()
    if not text or any(ch.isspace() for ch in text):
        return None
    if "/" in text:
        pieces = text.split("/")
        if len(pieces) == 3:
            package, middle, base = pieces
            if middle not in KINDS:
                return None
            explicit: Kind = "msg" if middle == "msg" else "srv" if middle == "srv" else "action"
            name, part = _split_part(explicit, base)
            return _make(package, explicit, name, part)
        if len(pieces) != 2:
            return None
        package, base = pieces
        legacy_halves = kind == "srv"
    elif "." in text:
        pieces = text.split(".")
        if len(pieces) != 2:
            return None
        package, base = pieces
        legacy_halves = kind in (None, "srv")
    else:
        return None
    if legacy_halves and (match := _LEGACY_HALF_RE.fullmatch(base)):
        half: Part = "request" if match["half"] == "Request" else "response"
        return _make(package, "srv", match["base"], half)
    return _make(package, kind or "msg", base)


def normalize_type_name(raw: str, kind: Kind | None = None) -> str | None:
    """The canonical interface name for what a TD wrote (see `parse_type_name`), or None if malformed.

    Service halves normalise to their service (`pkg.FooRequest` → `pkg/srv/Foo`); use `parse_type_name`
    to learn which half was meant.
    """
    parsed = parse_type_name(raw, kind)
    return parsed.canonical if parsed is not None else None


def split_canonical(name: str) -> tuple[str, Kind, str] | None:
    """`pkg/kind/Name` (suffixes like `_Request` included in Name) → its three pieces, or None."""
    pieces = name.split("/")
    if len(pieces) != 3 or pieces[1] not in KINDS:
        return None
    package, middle, base = pieces
    kind: Kind = "msg" if middle == "msg" else "srv" if middle == "srv" else "action"
    stem, _ = _split_part(kind, base)
    if not (is_valid_package_name(package) and is_valid_type_name(stem)):
        return None
    return package, kind, base


def service_part_names(service: str, style: Literal["ros2", "ros1", "java"] = "ros2") -> tuple[str, str]:
    """Request and response names of service `pkg/srv/Name` (any spelling `parse_type_name` accepts).

    ros2: `pkg/srv/Name_Request` (how the registry stores them); ros1: `pkg/NameRequest` (genpy); java:
    `pkg.NameRequest` (rosjava, what the reference TDs put in `ros:serviceRequestType`).
    """
    parsed = parse_type_name(service, "srv")
    if parsed is None or parsed.kind != "srv":
        raise ValueError(f"not a service type name: {service!r}")
    pkg, base = parsed.package, parsed.name
    if style == "ros2":
        return f"{pkg}/srv/{base}_Request", f"{pkg}/srv/{base}_Response"
    sep = "/" if style == "ros1" else "."
    return f"{pkg}{sep}{base}Request", f"{pkg}{sep}{base}Response"


def action_part_names(action: str) -> tuple[str, str, str]:
    """Goal, result and feedback message names of action `pkg/action/Name`."""
    parsed = parse_type_name(action, "action")
    if parsed is None or parsed.kind != "action":
        raise ValueError(f"not an action type name: {action!r}")
    base = parsed.canonical
    return f"{base}_Goal", f"{base}_Result", f"{base}_Feedback"


def ros1_name(name: str) -> str:
    """`pkg/msg/Name` → `pkg/Name`, the spelling ROS 1 tools and md5 texts use; the parts of services and
    actions lose their `_`: `pkg/action/Name_Goal` → `pkg/NameGoal` (genpy's class, genaction's message)."""
    pieces = name.split("/")
    if len(pieces) == 3:
        base = pieces[2].replace("_", "") if pieces[1] in ("srv", "action") else pieces[2]
        return f"{pieces[0]}/{base}"
    return name


#: the messages genaction derives from a ROS 1 action `pkg/action/Name`, besides its goal, result and
#: feedback: `pkg/msg/NameAction`, `pkg/msg/NameActionGoal`, ... (real messages of the package in ROS 1)
ROS1_ACTION_MESSAGES = ("Action", "ActionGoal", "ActionResult", "ActionFeedback")


def ros1_action_messages(action: str) -> tuple[str, str, str, str]:
    """The four derived ROS 1 messages of action `pkg/action/Name` (see ROS1_ACTION_MESSAGES)."""
    package, _, name = action.split("/")
    action_msg, goal, result, feedback = (f"{package}/msg/{name}{suffix}" for suffix in ROS1_ACTION_MESSAGES)
    return action_msg, goal, result, feedback


#: the types ROS 2 derives from an action for its hidden services and topic; a TD binds the action instead
_HIDDEN_ACTION_PART = re.compile(
    r"(?P<package>[a-z][a-z0-9_]*)/(?:(?:msg|srv|action)/)?(?P<name>[A-Z][A-Za-z0-9]*)_"
    r"(?P<part>SendGoal|GetResult|FeedbackMessage)(?:_(?:Request|Response|Event))?"
)


def hidden_action_part(raw: str) -> tuple[str, str] | None:
    """For a ROS 2 action's hidden type (`pkg/srv/Name_SendGoal`, `pkg/action/Name_GetResult`,
    `pkg/msg/Name_FeedbackMessage`, ...): the action `pkg/action/Name` and the part's name; else None."""
    match = _HIDDEN_ACTION_PART.fullmatch(raw.strip())
    if match is None:
        return None
    return f"{match['package']}/action/{match['name']}", match["part"]
