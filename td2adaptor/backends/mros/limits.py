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

The sizes of the connection headers are `_cxx.ros1wire`'s (exact for the fields ROS 1 sends).
What the generator cannot know — the peer's node name, the robot namespace chosen at build time — counts at
its largest allowed length. The message definition is genmsg's: the .msg files as written, comments included;
a type that did not come from a .msg file (the built-in ROS 1 store) counts without comments, a lower bound
(pass the robot's .msg files with `-I` for exact sizes).
"""

from __future__ import annotations

from dataclasses import dataclass

# ROS 1's connection headers are the same for any C/C++ backend with fixed buffers: the shared layer's
from td2adaptor.backends._cxx.ros1wire import SEPARATOR as SEPARATOR
from td2adaptor.backends._cxx.ros1wire import full_definition as full_definition
from td2adaptor.backends._cxx.ros1wire import header_size as header_size
from td2adaptor.backends._cxx.ros1wire import publisher_reply as publisher_reply
from td2adaptor.backends._cxx.ros1wire import subscriber_request as subscriber_request

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
