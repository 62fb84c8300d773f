"""Discovery at start (issue 11): how long after `serve()` a robot's TD is registered with a real TD directory
(Domus TDD on Oxigraph, .ci/setup-tdd.sh), next to how long until its retained TD is on the broker (a client
sees it) and to one plain PUT of the same document to the same directory (the directory's own cost), all in
this run, over a real mosquitto. The robot is the simulated RB-1: with the GoTo component and the door only
(the TD the JSON round-trip tests use), and whole.
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from td2adaptor.runtime import RuntimeConfig, serve  # noqa: E402
from td2adaptor.runtime.node.app import td_message  # noqa: E402
from td2adaptor.runtime.node.discovery import Directory, registration_document  # noqa: E402
from td2adaptor.runtime.ros.simport import SimPort  # noqa: E402

RUNS = 5


def ms(xs: list[float]) -> str:
    return f"median {statistics.median(xs) * 1000:.0f} ms (min {min(xs) * 1000:.0f}, max {max(xs) * 1000:.0f})"


def measure(model: Any, broker: Any, directory: Any, label: str) -> None:
    """RUNS starts of one robot of `model`: the three figures of the module docstring, printed."""
    from tests.runtime.client import AppClient
    from tests.runtime.rb1 import sim

    registered: list[float] = []
    published: list[float] = []
    direct: list[float] = []
    size = 0
    for run in range(RUNS):
        robot = f"bench_{label}_{run}"
        config = RuntimeConfig(robot=robot, bus=broker.url, property_period=0, state_dir="", directory=directory.url)
        seen = threading.Event()
        app = AppClient(broker.url, [f"td2adaptor/{robot}/td"])
        app.client.on_message = lambda *_a, _seen=seen, **_k: _seen.set()
        t0 = time.monotonic()
        engine = serve(model, SimPort(model, sim()), config)
        seen.wait(30)
        published.append(time.monotonic() - t0)
        registration: Any = engine.on_stop[0].__self__  # the Registration serve() started
        deadline = time.monotonic() + 60
        while registration.registered_at is None and time.monotonic() < deadline:
            time.sleep(0.005)
        assert registration.registered_at is not None, registration.last_error
        registered.append(registration.registered_at - t0)
        engine.stop()
        app.close()
        message = td_message(config, model)
        assert message is not None
        document = registration_document(message.payload, config.directory_ttl)
        size = len(json.dumps(document))
        client = Directory(directory.url)
        t0 = time.monotonic()
        client.put(str(document["id"]), document)
        direct.append(time.monotonic() - t0)
        client.delete(str(document["id"]))
    print(f"{label}: {RUNS} runs, TD of {size // 1024} KiB as registered (compact JSON)")
    print(f"  serve() -> retained TD seen on the broker:    {ms(published)}")
    print(f"  serve() -> TD registered with the directory:  {ms(registered)}")
    print(f"  baseline: one PUT of the same TD to it:       {ms(direct)}")


def main() -> int:
    from tests.runtime.broker import Mosquitto
    from tests.runtime.rb1 import compile_td, rb1_model
    from tests.runtime.tdd import VENV, TddServer, small_robot_td

    if not (VENV / "bin" / "flask").is_file():
        print(f"skipped: no TD directory in {VENV} (bash .ci/setup-tdd.sh)")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        broker = Mosquitto(base / "broker")
        broker.start()
        directory = TddServer(base / "tdd", clear_period=3600)
        directory.start()
        try:
            measure(compile_td(small_robot_td(base)), broker, directory, "goto-and-door")
            measure(rb1_model(), broker, directory, "whole-rb1")
        finally:
            directory.stop()
            broker.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
