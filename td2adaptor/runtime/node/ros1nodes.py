"""Is a node the ROS 1 master lists still running?

A ROS 1 node that stops cleanly unregisters from the master at once, but one that is killed (SIGKILL, a crash,
its host powered off) stays registered until something finds it dead (`rosnode cleanup`): the master keeps
naming it as the provider of its services and the publisher of its topics, and a call to it waits for its
timeout. So presence (presence.py) and discovery (graphwatch.py) do what `rosnode ping` does, more cheaply:
they connect to the node's XML-RPC API (its URI from the master's `lookupNode`) and close at once. A refused or
timed-out connection is a dead node. The URI is kept until a connection fails (then looked up again: a node
restarted under its old name has a new one), and each answer serves every look of the process for
`NODE_FRESH` seconds, so a node is tried at most about once a second whatever the number of robots on it.

A node whose port another process took after it died would pass for alive; the master would hand out its old
URI as well, so a call would fail as before.
"""

from __future__ import annotations

import http.client
import socket
import threading
import time
import urllib.parse
import xmlrpc.client
from collections.abc import Callable, Iterable
from typing import Any

#: seconds a connection to a node's XML-RPC API (and a `lookupNode`) may take; how long an answer serves
NODE_TIMEOUT, NODE_FRESH = 0.5, 1.0
CALLER_ID = "/td2adaptor_presence"
KEPT = 1024  # nodes remembered before those not asked about for a while are forgotten

_uris: dict[tuple[str, str], str] = {}  # (master, node) -> the node's XML-RPC URI
_alive: dict[tuple[str, str], tuple[float, bool]] = {}  # (master, node) -> when it was tried, and the answer
_lock = threading.Lock()


class TimeoutTransport(xmlrpc.client.Transport):
    """XML-RPC over HTTP that gives up after `timeout` seconds (the standard transport waits for ever)."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self.timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self.timeout
        return connection


def _lookup(master: str, node: str) -> str | None:
    """The node's XML-RPC URI as the master has it; None when the master does not know it or does not answer."""
    try:
        with xmlrpc.client.ServerProxy(master, transport=TimeoutTransport(NODE_TIMEOUT)) as proxy:
            answer: Any = proxy.lookupNode(CALLER_ID, node)
        code, _message, uri = answer
    except (OSError, xmlrpc.client.Error, TypeError, ValueError):
        return None
    return str(uri) if code == 1 and uri else None


def _answers(uri: str) -> bool:
    """Does something accept connections at `uri`'s host and port?"""
    parts = urllib.parse.urlsplit(uri)
    if not parts.hostname or not parts.port:
        return False
    try:
        socket.create_connection((parts.hostname, parts.port), timeout=NODE_TIMEOUT).close()
    except OSError:
        return False
    return True


def _try(master: str, node: str) -> bool:
    key = (master, node)
    with _lock:
        uri = _uris.get(key)
    if uri is not None and _answers(uri):
        return True
    fresh = _lookup(master, node)  # restarted under its old name? (None: the master knows it no more)
    if fresh is None or fresh == uri:
        return False
    with _lock:
        _uris[key] = fresh
    return _answers(fresh)


def alive(master: str, nodes: Iterable[str], clock: Callable[[], float] = time.monotonic) -> set[str]:
    """Those of `nodes` (names the master at `master` lists) that run: their XML-RPC API accepts a connection."""
    now = clock()
    running: set[str] = set()
    for node in set(nodes):
        key = (master, node)
        with _lock:
            known = _alive.get(key)
        if known is not None and now - known[0] < NODE_FRESH:
            answer = known[1]
        else:
            answer = _try(master, node)
            with _lock:
                _alive[key] = (clock(), answer)
        if answer:
            running.add(node)
    with _lock:
        if len(_alive) > KEPT:  # nodes gone long ago (a fleet whose robots come and go): forget them
            for key in [k for k, (when, _answer) in _alive.items() if now - when > 10 * NODE_FRESH]:
                del _alive[key]
                _uris.pop(key, None)
    return running
