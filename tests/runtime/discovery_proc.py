"""An edge node serving the simulated robot in its own process, registered with a TD directory (so a test can
kill it or stop it): `python -m tests.runtime.discovery_proc BUS ROBOT TD DIRECTORY TTL TD_BROKER`.
SIGTERM stops it cleanly (the TD is deregistered); SIGKILL leaves the directory to the TD's expiry."""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path

from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import compile_td, sim


def main() -> None:
    bus, robot, td, directory, ttl, td_broker = sys.argv[1:7]
    model = compile_td(Path(td))
    config = RuntimeConfig(
        robot=robot,
        bus=bus,
        td_broker=td_broker,
        directory=directory,
        directory_ttl=int(ttl),
        property_period=0,
        state_dir="",
    )
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    engine = serve(model, SimPort(model, sim()), config)
    print("ready", flush=True)
    stop.wait()
    engine.stop()


if __name__ == "__main__":
    main()
