"""A standard WoT client uses a robot as a Thing: Eclipse Thingweb node-wot with its MQTT binding, from npm,
fetches the robot's TD where the edge node publishes it (retained on td2adaptor/<robot>/td, the text
`td2adaptor expose` writes), consumes it as published, reads and observes poseMarker, invokes gotoRun and
receives its feedback event, on a real mosquitto (the simulated robot behind a SimPort: the consumer side is
under test).

Optional: skipped, saying why, when node/npm are missing or the packages cannot be installed (offline).
node-wot is installed once into .cache/node-wot with `npm install --ignore-scripts` (pure JavaScript).

node-wot 0.8 takes the MQTT topic from the form's href path and ignores `mqv:topic`/`mqv:filter`: the exposed
TD puts it in both, and node-wot consumes the TD as generated, nothing rewritten.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from td2adaptor.backends.events.generator import dump, exposed_td
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros2build import file_lock
from td2adaptor.runtime.simport import SimPort
from tests.conftest import REPO
from tests.runtime.broker import Mosquitto
from tests.runtime.rb1 import check_outbound, rb1_model, sim

NODE_WOT = "0.8.16"
CACHE = REPO / ".cache" / "node-wot"
CLIENT = Path(__file__).parent / "nodewot_client.js"
ROBOT = "wot_rb1"


def node_modules() -> Path:
    """node-wot's node_modules, installed on first use; skips the test when that is impossible."""
    if shutil.which("node") is None or shutil.which("npm") is None:
        pytest.skip("node and npm are not installed (apt install nodejs npm), so node-wot cannot run")
    modules = CACHE / "node_modules"
    wanted = [modules / "@node-wot" / name / "package.json" for name in ("core", "binding-mqtt")]
    with file_lock(REPO / ".cache" / "node-wot.lock"):
        if not all(p.is_file() for p in wanted):
            CACHE.mkdir(parents=True, exist_ok=True)
            (CACHE / "package.json").write_text('{"name": "td2adaptor-node-wot", "private": true}\n')
            args = ["npm", "install", "--ignore-scripts", "--no-audit", "--no-fund", "--loglevel=error"]
            args += [f"@node-wot/core@{NODE_WOT}", f"@node-wot/binding-mqtt@{NODE_WOT}"]
            try:
                out = subprocess.run(args, cwd=CACHE, capture_output=True, text=True, timeout=240)
            except subprocess.TimeoutExpired:
                pytest.skip("npm install of node-wot took longer than 240 s (no registry access?)")
            if out.returncode != 0:
                pytest.skip(f"npm could not install node-wot {NODE_WOT}: {out.stderr.strip()[-300:]}")
    installed = json.loads(wanted[1].read_text(encoding="utf-8"))["version"]
    assert installed == NODE_WOT
    return modules


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    b = Mosquitto(tmp_path / "broker")
    b.start()
    yield b
    b.stop()


def test_node_wot_consumes_the_published_td_reads_observes_invokes_and_gets_feedback(broker: Mosquitto) -> None:
    modules = node_modules()
    model = rb1_model()
    config = RuntimeConfig(robot=ROBOT, bus=broker.url, poll_period=0.05, property_period=0.1)
    engine = serve(model, SimPort(model, sim(0.3)), config)
    try:
        out = subprocess.run(
            ["node", str(CLIENT), broker.url, ROBOT, "wot-1"],
            env={**os.environ, "NODE_PATH": str(modules)},
            capture_output=True,
            text=True,
            timeout=30,
        )
    finally:
        engine.stop()
    lines = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    assert out.returncode == 0, out.stdout + out.stderr
    # node-wot consumed the TD the edge node published, byte for byte what `td2adaptor expose` writes
    (td,) = [line["value"] for line in lines if line["kind"] == "td"]
    assert td == dump(exposed_td(model, robot=ROBOT, broker=broker.url))
    kinds = [line["kind"] for line in lines]
    assert kinds.index("read") < kinds.index("subscribed") < kinds.index("invoked") and kinds[-1] == "done", kinds
    (read,) = [line["value"] for line in lines if line["kind"] == "read"]  # the retained value
    assert read["type"] == "property" and read["affordance"] == "poseMarker" and read["robot"] == ROBOT
    feedback = [line["value"] for line in lines if line["kind"] == "feedback"]
    mine = [e for e in feedback if e["correlation"] == "wot-1"]
    states = [e["payload"]["state"] for e in mine]
    assert states in (["queued", "running", "finished"], ["queued", "finished"]), states  # `running` if polled
    assert mine[-1]["payload"]["terminal"] is True and mine[-1]["robot"] == ROBOT
    values = [line["value"] for line in lines if line["kind"] == "property"]
    assert values and all(v["type"] == "property" and v["affordance"] == "poseMarker" for v in values)
    assert isinstance(values[-1]["payload"]["markers"], list)
    # what node-wot received is what the schemas describe
    topic = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun/feedback"
    check_outbound([(topic, e) for e in mine])
