"""Free loopback ports for the servers tests start (brokers, ROS masters, directories).

Not from the kernel's ephemeral range (`bind(0)` picks from it): the kernel gives those ports to outgoing
connections too, so a broker that a test stops and starts again on its port could find it taken by some
client's connection in between ("Address already in use", seen on a loaded machine). Below the range, only
another server that picks the same port at random can take it: one chance in thousands, and never one that
a connection takes.
"""

from __future__ import annotations

import random
import socket
from pathlib import Path

#: where the kernel's ephemeral range starts (Linux's default is 32768); ports are picked below it
_RANGE = Path("/proc/sys/net/ipv4/ip_local_port_range")
LOWEST = 20000


def _ephemeral_start() -> int:
    try:
        return int(_RANGE.read_text(encoding="ascii").split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port() -> int:
    """A loopback TCP port nobody listens on or is bound to now, outside the ephemeral range."""
    top = _ephemeral_start()
    low = LOWEST if top - LOWEST >= 2000 else 1024
    for _ in range(200):
        port = random.randrange(low, top)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError(f"no free loopback port between {low} and {top}")
