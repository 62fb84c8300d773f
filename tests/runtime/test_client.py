"""The tests' stand-in application client (tests/runtime/client.py) leaves nothing for the garbage collector to
close: a socket it closes in any order warns (`ResourceWarning`, an error under the suite's `filterwarnings`),
which failed a session's end at random."""

from __future__ import annotations

import gc
import weakref
from pathlib import Path

from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient


def test_a_closed_app_client_closes_its_sockets_when_dropped_without_a_collection(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    enabled = gc.isenabled()
    gc.disable()
    try:
        app = AppClient(broker, ["nothing/#"])
        pair = app.client._sockpairR  # made by paho's loop_start()
        assert pair is not None
        gone = weakref.ref(app.client)
        app.close()
        del app
        assert gone() is None and pair.fileno() == -1  # freed and closed by reference counting alone
    finally:
        if enabled:
            gc.enable()
        broker.stop()
