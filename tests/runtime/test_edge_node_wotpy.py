"""A second WoT client nobody here wrote: wotpy 0.18 (PyPI, pinned, in its own environment made by
.ci/setup-wotpy.sh) consumes the TD the edge node publishes, as published, on a real mosquitto.

What wotpy's MQTT client can do with a W3C MQTT binding TD, and what it cannot (README, "WoT consumers"):
it parses and consumes the TD and subscribes to events and property changes (the notifications arrive), but
it reads a notification's data from a `data` (event) or `value` (property) member of its own message format,
so the bare data of the binding comes out as None; and it invokes, reads and writes with its own request /
reply protocol (`{"id", "input"}` then a reply on `<topic>/result`), which only a wotpy server answers: the
robot refuses the wrapped goal with an error event, and wotpy's invocation times out.

Skipped, saying why, when .cache/wotpy is missing (run bash .ci/setup-wotpy.sh).
"""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path
from typing import Any

from td2adaptor.model.exposed import exposed_td
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from td2adaptor.support.jsondump import dump
from tests.conftest import REPO
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.rb1 import GOAL, rb1_model, sim
from tests.tools import missing

WOTPY = REPO / ".cache" / "wotpy" / "bin" / "python"
CLIENT = Path(__file__).parent / "wotpy_client.py"
ROBOT = "wotpy_rb1"
WOT = f"td2adaptor/{ROBOT}/wot-thing"


def _line(proc: subprocess.Popen[str], deadline: float) -> dict[str, Any]:
    assert proc.stdout is not None
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if line.startswith("{"):
            parsed: dict[str, Any] = json.loads(line)
            return parsed
    raise AssertionError(f"wotpy said nothing more (exit {proc.poll()})")


def test_wotpy_consumes_the_published_td_and_gets_notifications(broker: Mosquitto) -> None:
    if not WOTPY.is_file():
        missing(f"wotpy is not installed in {WOTPY.parent.parent} (run bash .ci/setup-wotpy.sh)")
    model = rb1_model()
    config = RuntimeConfig(robot=ROBOT, bus=broker.url, poll_period=0.05, property_period=0.1, state_dir="")
    engine = serve(model, SimPort(model, sim(0.3)), config)
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"])
    proc = subprocess.Popen(
        [str(WOTPY), str(CLIENT), broker.url, ROBOT], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 60
        seen: dict[str, Any] = {}
        while "subscribed" not in seen:
            line = _line(proc, deadline)
            seen[line["kind"]] = line["value"]
        # another consumer starts a mission on the WoT topic (the goal's fields, as the TD declares)
        app.send(f"{WOT}/GoToComponent/gotoRun", {**GOAL, "correlationId": "from-app"})
        while "invoked" not in seen and "invoke-failed" not in seen:
            line = _line(proc, deadline)
            seen[line["kind"]] = line["value"]
        assert proc.wait(30) == 0
        # wotpy's own invocation reached the robot wrapped in wotpy's request format: refused, in words
        app.wait(lambda ev: any(t == f"{WOT}/error" and e.get("affordance") == "gotoRun" for t, e in ev))
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()  # closes its pipes
        engine.stop()
        app.close()
    # wotpy parsed and consumed the TD as the edge node published it
    assert seen["td"] == dump(exposed_td(model, robot=ROBOT, broker=broker.url))
    assert {"gotoRun", "gotoQuery", "gotoCancel"} <= set(seen["consumed"]["actions"])
    # its subscriptions work: the notifications arrive, but wotpy looks for its own `data` / `value` members
    assert len(seen["events"]) >= 2 and seen["events"] == [None] * len(seen["events"])
    assert seen["values"] and set(map(str, seen["values"])) == {"None"}
    # its request/reply invocation is no MQTT binding's: nobody answers on <topic>/result
    assert seen.get("invoke-failed") == "ClientRequestTimeout", seen
    (refused,) = [e for t, e in app.events if t == f"{WOT}/error" and e.get("affordance") == "gotoRun"][:1]
    assert refused["code"] == "invalid-event" and "('id', 'input' were unexpected)" in refused["message"]
