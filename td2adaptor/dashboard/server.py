"""`td2adaptor dashboard`: connect to the bus, listen on a loopback address (by default), serve the page until
SIGINT/SIGTERM (uvicorn handles both and closes the event streams)."""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Callable
from dataclasses import dataclass

from td2adaptor.dashboard.app import create_app
from td2adaptor.dashboard.connection import BusSettings, open_dashboard_bus
from td2adaptor.dashboard.fleet import Fleet
from td2adaptor.runtime.bus.security import is_loopback

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
    return sorted({listen.host, "localhost", "127.0.0.1"} if listen.loopback else {listen.host})


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
    bus = open_dashboard_bus(options.bus)
    fleet = Fleet(options.topic_root)
    fleet.attach(bus)
    bus.connect()
    sock = None
    try:
        sock = _bind(options.listen)
        port = int(sock.getsockname()[1])
        app = create_app(fleet, bus, read_only=options.read_only, hosts=_hosts(options.listen))
        config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off", timeout_graceful_shutdown=2)
        mode = ", read-only" if options.read_only else ""
        say(f"serving {options.listen.url(port)} (bus {bus.address}{mode}); SIGINT/SIGTERM stops")
        uvicorn.Server(config).run(sockets=[sock])
    finally:
        fleet.close()
        bus.close()
        if sock is not None:
            sock.close()
