"""The rosbags typestores of ROS 1 Noetic and ROS 2 Jazzy, as the registry's bottom layer.

rosbags is imported lazily (it costs tens of milliseconds), each typestore is built once per process, and
its field definitions are cached on disk so that a CLI run needs the typestore itself only for serialisation.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from td2adaptor.model import ArrayKind, Constant, FieldType, MessageDef, MessageField
from td2adaptor.model.primitives import STRINGS

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

Distro = Literal["ros1", "ros2"]

STORE_NAMES: dict[Distro, str] = {"ros1": "ROS1_NOETIC", "ros2": "ROS2_JAZZY"}
# ROS 1 spells these as primitives; ROS 2 (and rosbags) as builtin_interfaces messages
TIME_TYPES = {"time": "builtin_interfaces/msg/Time", "duration": "builtin_interfaces/msg/Duration"}
TIME_MESSAGES = {v: k for k, v in TIME_TYPES.items()}


def store_label(distro: Distro) -> str:
    """The typestore's name as shown to users (`ros2_jazzy`)."""
    return STORE_NAMES[distro].lower()


@cache
def base_store(distro: Distro) -> Typestore:
    """The rosbags typestore of `distro`; shared, so never mutated."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores[STORE_NAMES[distro]])


@cache
def base_fielddefs(distro: Distro) -> dict[str, Any]:
    """The typestore's field definitions as plain data.

    Building a rosbags typestore generates a dataclass per type (~80 ms a distro); the definitions alone are
    cached on disk, keyed by the installed rosbags store module, so a CLI run needs the typestore only for
    serialisation.
    """
    import importlib.util

    from td2adaptor.support import cache

    key = ""
    spec = importlib.util.find_spec("rosbags")
    if spec is not None and spec.submodule_search_locations:
        module = Path(next(iter(spec.submodule_search_locations))) / "typesys" / "stores"
        module = module / f"{store_label(distro)}.py"
        try:
            st = module.stat()
            key = f"rosbags-{store_label(distro)}-{st.st_size}-{int(st.st_mtime)}.json"
        except OSError:
            key = ""
    if key:
        cached = cache.read_json(key)
        if isinstance(cached, dict):
            return cached
    data = {
        name: [[list(c) for c in consts], [[fname, _plain_desc(desc)] for fname, desc in fields]]
        for name, (consts, fields) in base_store(distro).fielddefs.items()
    }
    if key:
        cache.write_json(key, data)
    return data


def _plain_desc(desc: Any) -> Any:
    node, args = desc
    if int(node) in (3, 4):
        return [int(node), [_plain_desc(args[0]), int(args[1])]]
    if int(node) == 2:
        return [2, str(args)]
    return [int(node), [str(args[0]), int(args[1])]]


_BASE_DEFS: dict[tuple[Distro, str], MessageDef] = {}


def _convert_desc(desc: Any, distro: Distro) -> FieldType:
    """A rosbags field descriptor `(Nodetype, args)` → FieldType (Nodetype is an IntEnum: 1..4)."""
    node, args = desc
    if node in (3, 4):  # ARRAY, SEQUENCE
        inner_desc, size = args
        inner = _convert_desc(inner_desc, distro)
        kind = ArrayKind.FIXED if node == 3 else ArrayKind.SEQUENCE
        return FieldType(inner.base, inner.is_message, kind, int(size), inner.string_bound)
    if node == 2:  # NAME
        name = str(args)
        if distro == "ros1" and name in TIME_MESSAGES:
            return FieldType(TIME_MESSAGES[name])
        return FieldType(name, is_message=True)
    base, bound = args
    return FieldType(str(base), string_bound=int(bound) if base in STRINGS else 0)


def base_message(distro: Distro, name: str) -> MessageDef | None:
    """A typestore message as a model MessageDef (converted once per process)."""
    key = (distro, name)
    found = _BASE_DEFS.get(key)
    if found is not None:
        return found
    if distro == "ros1" and name in TIME_MESSAGES:
        return None  # ROS 1 has `time`/`duration` primitives, no builtin_interfaces package
    fielddefs = base_fielddefs(distro).get(name)
    if fielddefs is None:
        return None
    consts, fields = fielddefs
    msg = MessageDef(
        name,
        tuple(
            MessageField(fname, _convert_desc(desc, distro))
            for fname, desc in fields
            if fname != "structure_needs_at_least_one_member"
        ),
        tuple(Constant(cname, str(ctype), cvalue) for cname, ctype, cvalue in consts),
        origin=f"rosbags:{store_label(distro)}",
    )
    _BASE_DEFS[key] = msg
    return msg


def to_rosbags(msg: MessageDef) -> tuple[list[tuple[str, str, Any]], list[tuple[str, Any]]]:
    """A model message → rosbags field definitions, to register a user type in a typestore."""
    from rosbags.interfaces import Nodetype

    def desc(ftype: FieldType) -> Any:
        inner: tuple[Any, Any]
        if ftype.is_message:
            inner = (Nodetype.NAME, ftype.base)
        elif ftype.base in TIME_TYPES:
            inner = (Nodetype.NAME, TIME_TYPES[ftype.base])
        else:
            inner = (Nodetype.BASE, (ftype.base, ftype.string_bound))
        if ftype.array is ArrayKind.NONE:
            return inner
        node = Nodetype.ARRAY if ftype.array is ArrayKind.FIXED else Nodetype.SEQUENCE
        return (node, (inner, ftype.length))

    consts = [(c.name, c.type, c.value) for c in msg.constants]
    return consts, [(f.name, desc(f.type)) for f in msg.fields]
