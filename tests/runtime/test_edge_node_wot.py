"""A standard WoT client uses a robot as a Thing: Eclipse Thingweb node-wot with its MQTT binding, from npm,
fetches the robot's TD where the edge node publishes it (retained on td2adaptor/<robot>/td, the text
`td2adaptor expose` writes), consumes it as published, reads and observes poseMarker, invokes gotoRun and
receives its feedback event, on a real mosquitto (the simulated robot behind a SimPort: the consumer side is
under test).

node-wot is installed into .cache/node-wot by .ci/setup-nodewot.sh (`npm install --ignore-scripts`: pure
JavaScript), which `.ci/setup.sh --test` runs.

node-wot 0.8 takes the MQTT topic from the form's href path and ignores `mqv:topic`/`mqv:filter`: the exposed
TD puts it in both, and node-wot consumes the TD as generated, nothing rewritten.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

from td2adaptor.model import Model
from td2adaptor.model.events import Kind, build_catalog
from td2adaptor.model.exposed import exposed_td
from td2adaptor.model.wot import wot_data, wot_specs
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from td2adaptor.support.jsondump import dump
from tests.conftest import REPO
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import until
from tests.runtime.rb1 import rb1_model, sim
from tests.tools import missing, require

NODE_WOT = "0.8.16"
CACHE = REPO / ".cache" / "node-wot"
CLIENT = Path(__file__).parent / "nodewot_client.js"
ROBOT = "wot_rb1"


def node_modules() -> Path:
    """node-wot's node_modules, as .ci/setup-nodewot.sh (run by .ci/setup.sh --test) installs them."""
    modules = CACHE / "node_modules"
    wanted = [modules / "@node-wot" / name / "package.json" for name in ("core", "binding-mqtt")]
    require("node", "apt install nodejs")
    if not all(p.is_file() for p in wanted):
        missing(f"node-wot {NODE_WOT} is not installed: run `bash .ci/setup-nodewot.sh` (or .ci/setup.sh --test)")
    installed = json.loads(wanted[1].read_text(encoding="utf-8"))["version"]
    assert installed == NODE_WOT, f"node-wot {installed} in {CACHE}, the tests pin {NODE_WOT}: run .ci/setup-nodewot.sh"
    return modules


def wot_schemas(model: Model) -> dict[str, dict[str, Any]]:
    """The strict schema (unknown keys forbidden) of what travels on each WoT topic of ROBOT, by TD name."""
    out: dict[str, dict[str, Any]] = {}
    for spec in wot_specs(build_catalog(model)):
        name = {Kind.FEEDBACK: "Feedback", Kind.STATE: "State"}.get(spec.kind, "")
        out[f"{spec.affordance}{name}" if spec.affordance else spec.kind.value] = wot_data(spec)
    return out


def test_node_wot_uses_the_robot_as_a_thing_through_the_scripting_api(broker: Mosquitto) -> None:
    modules = node_modules()
    model = rb1_model()
    robot = sim(1.0)
    config = RuntimeConfig(robot=ROBOT, bus=broker.url, poll_period=0.05, property_period=0.1, state_dir="")
    engine = serve(model, SimPort(model, robot), config)
    try:
        out = subprocess.run(
            ["node", str(CLIENT), broker.url, ROBOT],
            env={**os.environ, "NODE_PATH": str(modules)},
            capture_output=True,
            text=True,
            timeout=40,
        )
    finally:
        engine.stop()
    lines = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    assert out.returncode == 0, out.stdout + out.stderr
    # node-wot consumed the TD the edge node published, byte for byte what `td2adaptor expose` writes
    (td,) = [line["value"] for line in lines if line["kind"] == "td"]
    assert td == dump(exposed_td(model, robot=ROBOT, broker=broker.url))
    schemas = wot_schemas(model)

    def values(kind: str) -> list[Any]:
        return [line["value"] for line in lines if line["kind"] == kind]

    # every value node-wot received is the affordance's own data, exactly as the strict schema says
    for kind, name in (("read", "poseMarker"), ("observed", "poseMarker")):
        for value in values(kind):
            assert list(Draft202012Validator(schemas[name]).iter_errors(value)) == [], (kind, value)
    for name in ("gotoRunFeedback", "gotoRunState", "error"):
        for value in values(name):
            assert list(Draft202012Validator(schemas[name]).iter_errors(value)) == [], (name, value)
    (read,) = values("read")
    assert isinstance(read["markers"], list) and "payload" not in read  # no envelope
    # the robot's presence: its retained status, as the TD's presence property describes it
    (presence,) = values("presence")
    described = {k: v for k, v in json.loads(td)["properties"]["presence"].items() if k != "forms"}
    assert list(Draft202012Validator(described).iter_errors(presence)) == [], presence
    assert presence["payload"]["state"] == "online" and presence["payload"]["owner"]["pid"] == os.getpid()
    # the write reached the robot as the property's own data
    until(lambda: robot.door_command == 0.75, 5)
    # 1. followed to its terminal outcome, by the correlationId sent with the goal's fields
    first = [e for e in values("gotoRunFeedback") if e.get("correlationId") == "wot-1"]
    assert [e["state"] for e in first] in (["queued", "running", "finished"], ["queued", "finished"]), first
    assert first[-1]["terminal"] is True and [e["seq"] for e in first] == list(range(1, len(first) + 1))
    # 2. queried and cancelled while it ran
    second = [e for e in values("gotoRunFeedback") if e.get("correlationId") == "wot-2"]
    mission = second[0]["mission"]
    assert second[-1]["terminal"] is True and second[-1]["state"] == "cancelled", second
    (query,) = [e for e in values("gotoRunState") if e.get("correlationId") == "q-1"]
    (cancel,) = [e for e in values("gotoRunState") if e.get("correlationId") == "c-1"]
    assert query["mission"] == mission and query["state"] in ("queued", "running") and not query["terminal"]
    assert cancel["mission"] == mission and cancel["state"] == "cancelled"
    # 3. a goal its message cannot hold: refused before it reached the robot, in words, with a stable code
    (refused,) = [e for e in values("error") if e.get("correlationId") == "bad-1"]
    assert refused["code"] == "invalid-event" and refused["affordance"] == "pickRun"
    assert "'nope' was unexpected" in refused["message"] and "Port" not in refused["message"]
    assert refused["topic"] == f"td2adaptor/{ROBOT}/wot-thing/PickComponent/pickRun"
    assert robot.next_id == 2  # the two gotoRun missions; the refused pickRun never reached the robot
    # 4. unobserved and unsubscribed through the TD's one form per subscription: nothing more arrived there
    kinds = [line["kind"] for line in lines]
    after = kinds[kinds.index("unsubscribed") :]
    assert "observed" not in after and "error" not in after, after
    assert not [e for e in values("error") if e.get("correlationId") == "bad-2"]
    assert [e for e in values("gotoRunState") if e.get("correlationId") == "q-2"]


def test_a_nosec_td_is_exposed_as_basic_when_the_node_logs_in_and_node_wot_then_works(tmp_path: Path) -> None:
    """Issue 30, item 11: a TD that declares nosec, credentials configured, a broker that wants a password: the
    node logged in and published `nosec`, so node-wot presented no credentials and every operation failed
    "Not authorized". The published TD now says `basic` (as `expose --basic` writes it); node-wot, given the
    consumer's credentials for the Thing, does it all: reads, observes, writes, invokes, queries, cancels."""
    modules = node_modules()
    users = {ROBOT: "node-pass", "consumer": "consumer-pass"}
    broker = Mosquitto(tmp_path / "broker", users=users)
    broker.start()
    model = rb1_model()  # nosec
    robot = sim(1.0)
    config = RuntimeConfig(robot=ROBOT, bus=broker.url, poll_period=0.05, property_period=0.1, state_dir="")
    env = {"TD2ADAPTOR_MQTT_USERNAME": ROBOT, "TD2ADAPTOR_MQTT_PASSWORD": "node-pass"}
    try:
        engine = serve(model, SimPort(model, robot), config, env=env)
        try:
            out = subprocess.run(
                ["node", str(CLIENT), broker.url, ROBOT],
                env={
                    **os.environ,
                    "NODE_PATH": str(modules),
                    "WOT_USERNAME": "consumer",
                    "WOT_PASSWORD": "consumer-pass",
                },
                capture_output=True,
                text=True,
                timeout=40,
            )
            assert until(lambda: robot.door_command == 0.75, 5), out.stdout + out.stderr  # written with credentials
        finally:
            engine.stop()
    finally:
        broker.stop()
    assert out.returncode == 0, out.stdout + out.stderr
    lines = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    (td,) = [line["value"] for line in lines if line["kind"] == "td"]
    published = json.loads(td)
    assert published["security"] == ["basic_sc"] and published["securityDefinitions"]["basic_sc"]["scheme"] == "basic"
    assert td == dump(exposed_td(model, robot=ROBOT, broker=broker.url, authenticated=True))  # = expose --basic
    assert [line["value"] for line in lines if line["kind"] == "outcome"] == ["wot-1"]
    assert robot.next_id == 2  # both gotoRun missions reached the robot
