"""Stopping a registration while a PUT is still under way (a directory slow to store a large TD, as Domus is under
load): the DELETE stop sends can overtake that PUT, which then stores the TD again after the node said it was
removed (seen in a loaded full run of tests/runtime/test_discovery_ros2.py). The directory here is a small real
HTTP server whose PUT stores only after a delay, like a directory that turns the TD into RDF first."""

from __future__ import annotations

import http.server
import json
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from td2adaptor.runtime.node import discovery
from td2adaptor.runtime.node.discovery import Directory, Registration

THING = "urn:dev:wot:tests:slow-directory"
TD = json.dumps({"@context": "https://www.w3.org/2022/wot/td/v1.1", "id": THING, "title": "slow"})


class SlowDirectory(http.server.ThreadingHTTPServer):
    """`/things/{id}`: PUT stores after `put_delay` (the first PUT at once), DELETE removes at once."""

    def __init__(self) -> None:
        super().__init__(("127.0.0.1", 0), _Handler)
        self.things: dict[str, bytes] = {}
        self.puts = 0
        self.stored = 0  # PUTs whose TD is stored
        self.put_delay = 0.0
        self.lock = threading.Lock()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}"


class _Handler(http.server.BaseHTTPRequestHandler):
    server: SlowDirectory

    def log_message(self, *_args: Any) -> None:
        pass

    def _thing(self) -> str:
        from urllib.parse import unquote

        return unquote(self.path.removeprefix("/things/"))

    def do_PUT(self) -> None:  # noqa: N802 (http.server's name)
        body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
        with self.server.lock:
            self.server.puts += 1
            delay = self.server.put_delay if self.server.puts > 1 else 0.0
        time.sleep(delay)
        with self.server.lock:
            self.server.things[self._thing()] = body
            self.server.stored += 1
        self.send_response(201)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def do_GET(self) -> None:  # noqa: N802
        with self.server.lock:
            body = self.server.things.get(self._thing())
        self.send_response(200 if body is not None else 404)
        self.send_header("Content-Length", str(len(body or b"")))
        self.end_headers()
        self.wfile.write(body or b"")

    def do_DELETE(self) -> None:  # noqa: N802
        with self.server.lock:
            found = self.server.things.pop(self._thing(), None)
        self.send_response(204 if found is not None else 404)
        self.send_header("Content-Length", "0")
        self.end_headers()


@pytest.fixture
def directory() -> Iterator[SlowDirectory]:
    server = SlowDirectory()
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()


def test_a_put_still_under_way_when_the_node_stops_does_not_leave_the_td_registered(
    directory: SlowDirectory, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(discovery, "DELETE_TIMEOUT", 0.3)  # how long stop waits for the registering thread
    registration = Registration(Directory(directory.url), TD, robot="slow")
    registration.start()
    deadline = time.monotonic() + 10
    while registration.readable is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert THING in directory.things
    directory.put_delay = 1.5  # the next PUT is stored 1.5 s after it came: after stop's DELETE
    registration.reflect("absent")  # registers again at once, with the robot's presence
    deadline = time.monotonic() + 10
    while directory.puts < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert directory.puts == 2
    registration.stop()
    deadline = time.monotonic() + 10
    while directory.stored < 2 and time.monotonic() < deadline:  # the slow PUT landed
        time.sleep(0.01)
    assert directory.stored == 2
    assert THING not in directory.things, "the TD was stored again after the node removed it"
