"""ROS graph names: the robot-namespace placeholder, ROS 1 and ROS 2 validity, and package names.

Rules checked (both must hold, since one TD feeds rclpy, rospy and mROS backends):
* ROS 1: first character a letter, `/` or `~`; then letters, digits, `_`, `/`; no `//`.
* ROS 2: tokens separated by `/` must not be empty or start with a digit; no `__`; no trailing `/`.
"""

from __future__ import annotations

import keyword
import re

from td2adaptor.model import RosName

#: Placeholders for the robot namespace: the td2adaptor binding's and the reference system's.
BINDING_PLACEHOLDER = "{{robotName}}"
REFERENCE_PLACEHOLDER = "#robotName"

_ROS1 = re.compile(r"[~/]?[A-Za-z][A-Za-z0-9_/]*\Z")
_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def split_namespace(raw: str) -> tuple[RosName, str | None]:
    """Parse a name as written in a TD; returns the name and the placeholder spelling found, if any."""
    for placeholder in (BINDING_PLACEHOLDER, REFERENCE_PLACEHOLDER):
        for prefix in ("/" + placeholder + "/", placeholder + "/"):
            if raw.startswith(prefix):
                return RosName(raw[len(prefix) :], namespaced=True), placeholder
    return RosName(raw), None


def name_problems(name: RosName) -> list[str]:
    """Why `name` is not a valid ROS 1 and ROS 2 graph name (empty list when it is)."""
    full = name.resolve("ns") if name.namespaced else name.path
    problems: list[str] = []
    if not name.path:
        return ["the name is empty"]
    if "{{" in full or "#" in full:
        problems.append("a namespace placeholder may only start the name, as '/{{robotName}}/rest'")
        return problems
    if name.namespaced and name.path.startswith(("/", "~")):
        problems.append("the part after the namespace placeholder must be relative")
    if not _ROS1.match(full) or "//" in full:
        problems.append("not a valid ROS 1 name (a letter, '/' or '~' first, then letters, digits, '_' and single '/')")
    body = full.lstrip("~").lstrip("/")
    if full.endswith("/"):
        problems.append("a ROS 2 name must not end with '/'")
    elif body and any(not _TOKEN.match(tok) for tok in body.split("/")):
        problems.append("every '/'-separated token of a ROS 2 name must start with a letter or '_'")
    if "__" in full:
        problems.append("a ROS 2 name must not contain '__'")
    return problems


def namespace_problems(namespace: str) -> list[str]:
    """Problems with a robot namespace given at run time (e.g. `rb1_base_a`)."""
    ns = namespace.strip("/")
    if not ns:
        return []
    return name_problems(RosName("/" + ns))


_CPP_KEYWORDS = frozenset(
    """alignas alignof and and_eq asm auto bitand bitor bool break case catch char char16_t char32_t class
    compl const constexpr const_cast continue decltype default delete do double dynamic_cast else enum
    explicit export extern false float for friend goto if inline int long mutable namespace new noexcept
    not not_eq nullptr operator or or_eq private protected public register reinterpret_cast return short
    signed sizeof static static_assert static_cast struct switch template this thread_local throw true try
    typedef typeid typename union unsigned using virtual void volatile wchar_t while xor xor_eq""".split()
)
_IDENT = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")

#: Longest component, affordance or package name: they become file and folder names (with prefixes and
#: suffixes such as `.events.schema.json`), and file systems refuse names over 255 bytes.
MAX_NAME = 100


def identifier_problem(name: str) -> str | None:
    """Why `name` cannot be a class or method-name part in Python and C++ (None when it can)."""
    if not _IDENT.match(name):
        return "must start with a letter and contain only ASCII letters, digits and '_'"
    if len(name) > MAX_NAME:
        return f"is {len(name)} characters long, more than {MAX_NAME} (it becomes file and class names)"
    if keyword.iskeyword(name) or name in _CPP_KEYWORDS or name in {"None", "True", "False"}:
        return "is a reserved word in Python or C++"
    if "__" in name:
        return "must not contain '__' (reserved in C++)"
    return None


def package_name(title: str) -> str:
    """A ROS package name (REP 144) derived from a Thing title: `Robotnik RB-1` → `robotnik_rb_1_adaptor`."""
    base = re.sub(r"[^a-z0-9]+", "_", title.lower()).strip("_")
    base = re.sub(r"^[0-9_]+", "", base) or "thing"
    if base.endswith("_adaptor"):
        base = base[: -len("_adaptor")]
    return base[: MAX_NAME - len("_adaptor")].rstrip("_") + "_adaptor"


def package_name_problem(name: str) -> str | None:
    if not re.fullmatch(r"[a-z][a-z0-9]*(_[a-z0-9]+)*", name):
        return "must be lower-case letters and digits separated by single '_', starting with a letter"
    if len(name) > MAX_NAME:
        return f"is {len(name)} characters long, more than {MAX_NAME} (it becomes folder names)"
    return None
