"""Sizes of what mROS v1.3 exchanges with ROS 1 peers, against the fixed buffers of an mROS tree.

mROS keeps its protocol messages in static buffers whose sizes are compile-time constants of the mROS tree
(`mros-lib/mros-src/packet/cimpl/version/kinetic/mros_packet_config.h`, not `#ifndef`-guarded, so an
application cannot change them):

* `MROS_PACKET_MAXSIZE_REQ_TCPROS` / `MROS_PACKET_MAXSIZE_RES_TCPROS` (512 each): each TCPROS side keeps
  one buffer of the larger of the two. A subscriber reads the publisher's whole connection header into it,
  and a publisher the subscriber's, with the length taken from the wire and *no bound check*: a ROS 1
  peer's header carries the full message definition, so a type with a long definition overruns it.
* `MROS_PACKET_MAXSIZE_REQ_REGISTER_PUBLISHER` ... (1024 each): XML-RPC requests to the master; a request
  that does not fit is refused at run time (the topic never registers).

The sizes here are exact for the fields ROS 1 sends (rospy's `TCPROSPub`/`TCPROSSub.get_header_fields`,
roscpp's publisher sends the same fields as rospy's): each field is a 4-byte length, then `name=value`.
What the generator cannot know — the peer's node name, the robot namespace chosen at build time — counts at
its largest allowed length. The message definition is genmsg's: the .msg files as written, comments included;
a type that did not come from a .msg file (the built-in ROS 1 store) counts without comments, a lower bound
(pass the robot's .msg files with `-I` for exact sizes).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from td2adaptor.model import TypeTable

#: upstream mROS v1.3 values (mros_packet_config.h)
TCPROS_BUFFER = 512  # max(MROS_PACKET_MAXSIZE_REQ_TCPROS, MROS_PACKET_MAXSIZE_RES_TCPROS)
XMLRPC_BUFFER = 1024  # MROS_PACKET_MAXSIZE_REQ_REGISTER_PUBLISHER and the other XML-RPC buffers
PACKET_CONFIG = "mros-lib/mros-src/packet/cimpl/version/kinetic/mros_packet_config.h"
#: strlen of mROS's packet formats (mros_packet_fmt_http.h, mros_packet_fmt_xml.h)
HTTP_POST_FORMAT = 93
XML_REGISTER_FORMAT = 235
XML_REQUEST_TOPIC_FORMAT = 290
#: "http://255.255.255.255:11411", the longest slave URI mROS announces
SLAVE_URI_MAX = 28


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


def xmlrpc_register_size(node: str, topic: str, type_name: str) -> int:
    """What mROS's packet encoder reserves for registerPublisher/registerSubscriber (its bound check)."""
    args = ("registerSubscriber", node, topic, type_name, "x" * SLAVE_URI_MAX)
    return HTTP_POST_FORMAT + 1 + XML_REGISTER_FORMAT + 1 + sum(len(a.encode()) + 1 for a in args)


def xmlrpc_request_topic_size(node: str, topic: str) -> int:
    """What mROS reserves for its requestTopic call to a publisher."""
    args = ("requestTopic", node, topic, "TCPROS")
    return HTTP_POST_FORMAT + 1 + XML_REQUEST_TOPIC_FORMAT + 1 + sum(len(a.encode()) + 1 for a in args)


@dataclass(frozen=True)
class TopicSizes:
    """The largest protocol messages of one topic, in bytes."""

    prop: str
    topic: str  # as the README shows it
    role: str  # "publisher" or "subscriber"
    tcpros: int  # the peer's connection header mROS reads
    definition: int  # of which the message definition
    xmlrpc: int  # the largest XML-RPC request mROS encodes for it
    estimated: tuple[str, ...] = ()  # types counted without their comments (not read from .msg files)
