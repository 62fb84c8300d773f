"""ROS 1's TCPROS connection headers, as peers send them: what an embedded C/C++ client with fixed buffers
must be able to read (the full message definition included).

The sizes are exact for the fields ROS 1 sends (rospy's `TCPROSPub`/`TCPROSSub.get_header_fields`, roscpp's
publisher sends the same fields as rospy's): each field is a 4-byte length, then `name=value`. The message
definition is genmsg's: the .msg files as written, comments included; a type that did not come from a .msg
file (the built-in ROS 1 store) counts without comments, a lower bound.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from td2adaptor.model import TypeTable

SEPARATOR = "=" * 80 + "\n"


def _own_text(table: TypeTable, name: str) -> tuple[str, bool]:
    """A message's own definition as ROS 1 has it: its .msg file as written (comments included) when it came
    from one, else the normalised text (True: without the comments a ROS 1 peer's copy may have)."""
    origin = table.message(name).origin
    if origin.endswith(".msg") and Path(origin).is_file():
        return Path(origin).read_text(encoding="utf-8"), False
    full = table.ros1_digest(name).definition
    return full.split(SEPARATOR + "MSG: ", 1)[0], True


def full_definition(table: TypeTable, name: str) -> tuple[str, tuple[str, ...]]:
    """genmsg's `message_definition` of `name` (its text, then each message it uses after a `====` line and
    `MSG: pkg/Name`), and the types whose comments are unknown (counted without them)."""
    deps: list[str] = []

    def collect(msg: str) -> None:
        for f in table.message(msg).fields:
            if f.type.is_message and f.type.base not in deps:
                deps.append(f.type.base)
                collect(f.type.base)

    collect(name)
    text, estimated = _own_text(table, name)
    parts = [text + "\n"]
    unknown = [name] if estimated else []
    for dep in deps:
        dep_text, dep_estimated = _own_text(table, dep)
        parts.append(f"{SEPARATOR}MSG: {dep.replace('/msg/', '/')}\n{dep_text}\n")
        if dep_estimated:
            unknown.append(dep)
    return "".join(parts)[:-1], tuple(unknown)


def header_size(fields: Mapping[str, str]) -> int:
    """Bytes of a ROS 1 connection header after its own 4-byte length: per field a 4-byte length and
    `name=value` (UTF-8)."""
    return sum(4 + len(f"{name}={value}".encode()) for name, value in fields.items())


def publisher_reply(topic: str, type_name: str, md5: str, definition: str, callerid: str) -> dict[str, str]:
    """The header a ROS 1 publisher (rospy or roscpp) answers a subscriber with."""
    return {
        "topic": topic,
        "type": type_name,
        "latching": "0",
        "message_definition": definition,
        "md5sum": md5,
        "callerid": callerid,
    }


def subscriber_request(topic: str, type_name: str, md5: str, definition: str, callerid: str) -> dict[str, str]:
    """The header a rospy subscriber opens a connection with (roscpp's lacks `message_definition`)."""
    return {
        "topic": topic,
        "message_definition": definition,
        "tcp_nodelay": "0",
        "md5sum": md5,
        "type": type_name,
        "callerid": callerid,
    }
