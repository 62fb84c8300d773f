"""`td2adaptor dashboard`: connect to the bus, listen on a loopback address (by default), serve the page until
SIGINT/SIGTERM (uvicorn handles both and closes the event streams)."""

from __future__ import annotations

import ipaddress
import os
import signal
import socket
from collections.abc import Callable
from dataclasses import dataclass
from types import FrameType
from typing import Any

from td2adaptor.dashboard.app import create_app
from td2adaptor.dashboard.connection import BusSettings, open_dashboard_bus
from td2adaptor.dashboard.directory import DirectoryReader
from td2adaptor.dashboard.fleet import Fleet
from td2adaptor.runtime.bus.security import is_loopback, redact_url
from td2adaptor.runtime.config import check_directory_url, from_env

__all__ = ["DashboardError", "DashboardOptions", "Listen", "parse_listen", "serve_dashboard"]


class DashboardError(Exception):
    """The dashboard cannot start as asked; the message says what to change."""


@dataclass(frozen=True)
class Listen:
    host: str
    port: int

    @property
    def loopback(self) -> bool:
        return is_loopback(self.host)

    def url(self, port: int | None = None) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port if port is None else port}/"


@dataclass(frozen=True)
class DashboardOptions:
    bus: BusSettings
    listen: Listen
    read_only: bool = False
    allow_remote: bool = False
    topic_root: str = "td2adaptor"
    directory: str | None = None  # a TD directory to list robots from as well
    directory_period: float = 10.0  # seconds between two readings of its listing


def parse_listen(text: str) -> Listen:
    """`HOST:PORT` (`[v6]:PORT`); port 0 picks a free one."""
    host, colon, port = text.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not colon or not host or not port.isdigit() or int(port) > 65535:
        raise DashboardError(f"--listen {text!r}: give HOST:PORT, e.g. 127.0.0.1:8080")
    return Listen(host, int(port))


def _hosts(listen: Listen) -> list[str]:
    """The Host headers the page answers (others are refused: a DNS rebinding attack names another host)."""
    try:
        if ipaddress.ip_address(listen.host).is_unspecified:
            return ["*"]
    except ValueError:
        pass
    return sorted({listen.host, "localhost", "127.0.0.1", "::1"} if listen.loopback else {listen.host})


def _bind(listen: Listen) -> socket.socket:
    family = socket.AF_INET6 if ":" in listen.host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((listen.host, listen.port))
    except OSError as exc:
        sock.close()
        raise DashboardError(f"cannot listen on {listen.url()}: {exc.strerror or exc}") from None
    sock.listen(128)
    sock.set_inheritable(True)
    return sock


class _Server:
    """uvicorn's server, which first ends the pages' event streams (they never end on their own, and uvicorn
    waits for open requests) and then returns from `run` instead of dying of the signal it caught (uvicorn
    raises it again once stopped): the bus is closed cleanly and the command says it stopped."""

    def __init__(self, config: Any, closing: Callable[[], None]) -> None:
        import uvicorn

        class Server(uvicorn.Server):
            def handle_exit(self, sig: int, frame: FrameType | None) -> None:
                closing()
                super().handle_exit(sig, frame)

        self.server = Server(config)

    def run(self, sockets: list[socket.socket]) -> None:
        previous = signal.signal(signal.SIGTERM, lambda _sig, _frame: None)  # what uvicorn raises again
        try:
            self.server.run(sockets=sockets)
        finally:
            signal.signal(signal.SIGTERM, previous)


def serve_dashboard(options: DashboardOptions, say: Callable[[str], None]) -> None:
    """Run until interrupted. Raises `DashboardError`, `SecurityError`, `ConfigError` or `BusError` (each says
    what to change) before anything is served."""
    import uvicorn

    if not options.listen.loopback and not options.allow_remote:
        raise DashboardError(
            f"--listen {options.listen.host}: not a loopback address, and the page has no login of its own: "
            "anyone who reaches it could watch (and, unless --read-only, command) the robots; put it behind an "
            "authenticating proxy and pass --allow-remote, or listen on 127.0.0.1"
        )
    reader_url = None
    if options.directory is not None:
        try:
            reader_url = check_directory_url(options.directory)
        except ValueError as exc:
            raise DashboardError(str(exc)) from None
    bus = open_dashboard_bus(options.bus)
    fleet = Fleet(options.topic_root)
    fleet.attach(bus)
    bus.connect()
    sock = None
    reader = None
    try:
        if reader_url is not None:
            values = from_env(os.environ)
            reader = DirectoryReader(
                reader_url,
                fleet,
                token=values.get("directory_token"),
                ca_file=values.get("directory_ca_file"),
                period=options.directory_period,
            )
            reader.start()
        sock = _bind(options.listen)
        port = int(sock.getsockname()[1])
        app = create_app(fleet, bus, read_only=options.read_only, hosts=_hosts(options.listen))
        config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off", timeout_graceful_shutdown=2)
        mode = ", read-only" if options.read_only else ""
        listed = f", directory {redact_url(reader_url)}" if reader_url else ""
        say(f"serving {options.listen.url(port)} (bus {bus.address}{listed}{mode}); SIGINT/SIGTERM stops")
        _Server(config, fleet.shutdown).run(sockets=[sock])
    finally:
        if reader is not None:
            reader.stop()
        fleet.close()
        bus.close()
        if sock is not None:
            sock.close()
