"""A running ROS 1 graph, read from its master: system state and topic types over the master's XML-RPC API,
each service's type from its server's TCPROS header (a `probe` connection, as `rosservice type` does).

Both are plain protocols, so this needs neither rospy nor ROS 1's interpreter: td2adaptor's own Python
reads a Noetic graph wherever it can reach the master and the service ports.
"""

from __future__ import annotations

import os
import socket
import struct
import xmlrpc.client
from typing import Any
from urllib.parse import urlsplit

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.rostypes.names import normalize_type_name
from td2adaptor.scaffold.graph import Endpoint, Graph, Role

CALLER_ID = "/td2adaptor_scaffold"
_HEADER_LIMIT = 1 << 20


def encode_header(fields: dict[str, str]) -> bytes:
    """A TCPROS connection header: a little-endian length, then each `key=value` with its length."""
    body = b"".join(struct.pack("<I", len(f)) + f for f in (f"{k}={v}".encode() for k, v in fields.items()))
    return struct.pack("<I", len(body)) + body


def _recv(sock: socket.socket, n: int) -> bytes:
    data = b""
    while len(data) < n:
        chunk = sock.recv(n - len(data))
        if not chunk:
            raise ConnectionError("connection closed in the middle of a header")
        data += chunk
    return data


def decode_header(body: bytes) -> dict[str, str]:
    out: dict[str, str] = {}
    pos = 0
    while pos + 4 <= len(body):
        (size,) = struct.unpack_from("<I", body, pos)
        field = body[pos + 4 : pos + 4 + size].decode("utf-8", "replace")
        pos += 4 + size
        key, _, value = field.partition("=")
        out[key] = value
    return out


def service_type(uri: str, service: str, timeout: float) -> str:
    """The type a service's server declares in its TCPROS header (`rosrpc://host:port`)."""
    parts = urlsplit(uri)
    if parts.scheme != "rosrpc" or parts.hostname is None or parts.port is None:
        raise ValueError(f"not a rosrpc URI: {uri}")
    with socket.create_connection((parts.hostname, parts.port), timeout=timeout) as sock:
        sock.sendall(encode_header({"callerid": CALLER_ID, "service": service, "md5sum": "*", "probe": "1"}))
        (size,) = struct.unpack("<I", _recv(sock, 4))
        if size > _HEADER_LIMIT:
            raise ValueError(f"header of {size} bytes")
        header = decode_header(_recv(sock, size))
    if "error" in header:
        raise ValueError(header["error"])
    return header["type"]


def _call(master: Any, method: str, *args: Any) -> Any:
    code, message, value = getattr(master, method)(CALLER_ID, *args)
    if code != 1:
        raise ValueError(f"{method}: {message}")
    return value


def read(diags: Diagnostics, *, master_uri: str | None = None, timeout: float = 10.0) -> Graph | None:
    """The graph the master knows; None (SCF101) when no master answers."""
    uri = master_uri or os.environ.get("ROS_MASTER_URI") or "http://localhost:11311"
    previous = socket.getdefaulttimeout()
    socket.setdefaulttimeout(timeout)
    try:
        master = xmlrpc.client.ServerProxy(uri)
        publishers, subscribers, services = _call(master, "getSystemState")
        topic_types = dict(_call(master, "getTopicTypes"))
        uris = {name: _call(master, "lookupService", name) for name, _ in services}
    except (OSError, ValueError, xmlrpc.client.Error) as exc:
        diags.error("SCF101", f"no ROS 1 master answers at {uri}: {exc}", hint="start roscore, or give --master-uri")
        return None
    finally:
        socket.setdefaulttimeout(previous)
    graph = Graph(f"the ROS 1 graph of {uri}", distro="ros1")
    roles: tuple[tuple[Role, Any], ...] = (("publisher", publishers), ("subscriber", subscribers))
    for role, listing in roles:
        for topic, nodes in listing:
            canonical = normalize_type_name(topic_types.get(topic, ""), "msg")
            if canonical is not None:
                graph.endpoints.append(Endpoint("topic", topic, canonical, role, tuple(sorted(nodes))))
    for name, nodes in services:
        if name.rsplit("/", 1)[-1] in ("get_loggers", "set_logger_level"):
            continue  # every rospy node's; never probed
        try:
            raw = service_type(uris[name], name, timeout)
        except (OSError, ValueError, KeyError, struct.error) as exc:
            diags.warning("SCF107", f"service {name}: its type could not be read ({exc}); left out")
            continue
        canonical = normalize_type_name(raw, "srv")
        if canonical is not None:
            graph.endpoints.append(Endpoint("service", name, canonical, "server", tuple(sorted(nodes))))
    return graph
