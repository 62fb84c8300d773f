"""The Thing Description the edge node publishes (retained on td2adaptor/<robot>/td of a real mosquitto, as
`td2adaptor run` does; the RB-1's, and nav_base's with its ROS actions) conforms: to the official W3C TD 1.1
JSON Schema, to our own validator (`td2adaptor validate`), to the W3C MQTT binding template's JSON Schema, and
to the Thingweb Playground's core validator (npm, pinned by .ci/setup-wot.sh), whose only remark is one we
leave on purpose (see the last test)."""

from __future__ import annotations

import copy
import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.diagnostics import Severity
from td2adaptor.model import Model
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.node.app import td_message
from td2adaptor.runtime.ros.simport import SimPort
from tests import wot_corpus
from tests.conftest import REPO
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.rb1 import rb1_model, sim
from tests.tools import require

ROBOT = "rb1_conform"
BINDING_SCHEMA = wot_corpus.SHARED_WOT / "bindings" / "mqtt.schema.json"
PLAYGROUND = Path(__file__).parent / "playground_validate.js"


NAV_BASE = REPO / "examples" / "nav_base"


def nav_base_model() -> Model:
    result = td2adaptor.compile(NAV_BASE / "td.json", interfaces=[NAV_BASE / "interfaces"])
    assert result.model is not None, [d.message for d in result.diagnostics]
    return result.model


@pytest.fixture(scope="module", params=["rb1", "nav_base"])
def published(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """The TD as a client finds it on the broker while the robot is online: the RB-1's (procedures), and
    nav_base's, whose long tasks are ROS actions (their own queryaction/cancelaction forms, `goal` inputs)."""
    broker = Mosquitto(tmp_path_factory.mktemp("broker"))
    broker.start()
    if request.param == "rb1":
        model = rb1_model()
        port = SimPort(model, sim())
    else:  # only its TD is looked at: a port that has no value to give and writes nothing is enough
        model = nav_base_model()
        port = SimPort(model, sim(), readers={}, writers={})
    config = RuntimeConfig(robot=ROBOT, bus=broker.url, property_period=0, state_dir="")
    engine = serve(model, port, config)
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/td"])
    try:
        (_, td), *_ = app.wait(lambda ev: any("id" in e for _, e in ev), 20)
        message = td_message(config, model)
        assert message is not None and json.loads(message.payload) == td  # the text `run` publishes
        if request.param == "nav_base":  # what it is here for
            ops = [{f["op"] for f in a["forms"]} for a in td["actions"].values()]
            assert sum({"invokeaction", "queryaction", "cancelaction"} <= o for o in ops) >= 3, ops
        yield td
    finally:
        app.close()
        engine.stop()
        broker.stop()


def _errors(schema: Any, instance: Any, registry: Any = None) -> list[str]:
    from jsonschema import Draft7Validator, FormatChecker

    kw = {} if registry is None else {"registry": registry}
    validator = Draft7Validator(schema, format_checker=FormatChecker(), **kw)
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message[:200]}" for e in validator.iter_errors(instance)]


def test_the_published_td_passes_the_official_td_1_1_schema(published: dict[str, Any]) -> None:
    assert _errors(wot_corpus.official_json("td-schema-v1.1.json"), published) == []


def test_the_published_td_passes_our_validator(published: dict[str, Any], tmp_path: Path) -> None:
    path = tmp_path / "td.json"
    path.write_text(json.dumps(published), encoding="utf-8")
    result = td2adaptor.compile(path)
    assert [(d.code, d.message) for d in result.diagnostics if d.severity is Severity.ERROR] == []
    # ROS400: it has no ROS binding left (it is the robot seen over MQTT), which is the point of it
    assert {d.code for d in result.diagnostics if d.severity is Severity.WARNING} <= {"ROS400"}


def test_the_published_td_passes_the_w3c_mqtt_binding_schema(published: dict[str, Any]) -> None:
    if not BINDING_SCHEMA.is_file():
        pytest.skip("needs ../shared/wot/bindings/mqtt.schema.json (no registry package ships the binding's schema)")
    from referencing import Registry, Resource
    from referencing.jsonschema import DRAFT7

    binding = json.loads(BINDING_SCHEMA.read_text(encoding="utf-8"))
    td_uri = binding["anyOf"][0]["$ref"]  # the official TD schema by URL: resolved offline
    official = wot_corpus.official_json("td-schema-v1.1.json")
    registry = Registry().with_resource(td_uri, Resource.from_contents(official, DRAFT7))
    assert _errors(binding, published, registry) == []


def playground(td: dict[str, Any], tmp_path: Path) -> dict[str, Any]:
    """The Playground core validator's verdict on `td` (JSON-LD expansion off: it would fetch the contexts)."""
    package = wot_corpus.npm_package(wot_corpus.PLAYGROUND_PACKAGE)
    if package is None:
        pytest.skip(
            f"needs npm {wot_corpus.PLAYGROUND_PACKAGE}@{wot_corpus.NPM_VERSIONS[wot_corpus.PLAYGROUND_PACKAGE]}"
            f" ({wot_corpus.SETUP})"
        )
    require("node", "apt install nodejs")
    path = tmp_path / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    env = {**os.environ, "NODE_PATH": str(wot_corpus.NPM_MODULES)}
    out = subprocess.run(
        ["node", str(PLAYGROUND), str(path)], env=env, capture_output=True, text=True, timeout=120, cwd=REPO
    )
    assert out.returncode == 0, out.stderr
    return dict(json.loads(out.stdout))


def with_td_defaults_spelled_out(td: dict[str, Any]) -> dict[str, Any]:
    """`td` with every TD 1.1 default it leaves out written in, as the Playground's optional "defaults" check
    wants them: `readOnly` / `writeOnly: false` in every data schema (the property affordances and everything in
    the affordances' data), a property's `observable: false`, an action's `safe` / `idempotent: false`, and a
    form's `contentType: application/json`."""
    out = copy.deepcopy(td)

    def schema(node: Any) -> None:
        if not isinstance(node, dict):
            return
        node.setdefault("readOnly", False)
        node.setdefault("writeOnly", False)
        for sub in (node.get("properties") or {}).values():
            schema(sub)
        items = node.get("items")
        for sub in items if isinstance(items, list) else [items]:
            schema(sub)
        for key in ("oneOf", "anyOf", "allOf"):
            for sub in node.get(key) or []:
                schema(sub)

    for prop in out.get("properties", {}).values():
        schema(prop)
        prop.setdefault("observable", False)
    for action in out.get("actions", {}).values():
        schema(action.get("input"))
        schema(action.get("output"))
        action.setdefault("safe", False)
        action.setdefault("idempotent", False)
    for event in out.get("events", {}).values():
        schema(event.get("data"))
    for kind in ("properties", "actions", "events"):
        for affordance in out.get(kind, {}).values():
            for form in affordance["forms"]:
                form.setdefault("contentType", "application/json")
    return out


def test_the_published_td_passes_the_thingweb_playground_validator(published: dict[str, Any], tmp_path: Path) -> None:
    verdict = playground(published, tmp_path)
    report, details = verdict["report"], verdict["details"]
    assert (report["json"], report["schema"], report["additional"]) == ("passed", "passed", "passed"), verdict
    off = {"linkedAffordances", "linkedStructure"}  # the TD links no Thing Model
    assert {k: v for k, v in details.items() if k not in off} == dict.fromkeys(set(details) - off, "passed")
    # The one remark: the optional "defaults" check warns that the TD leaves members to their TD 1.1 defaults
    # (readOnly/writeOnly false in hundreds of payload schemas, a form's contentType application/json, ...).
    # Spelling them out would tell a consumer nothing it does not know already and make the TD too large for
    # a directory (docs/fleet.md); so it stays, and nothing else may be behind it:
    if report["defaults"] != "passed":
        assert report["defaults"] == "warning", verdict
        again = playground(with_td_defaults_spelled_out(published), tmp_path)
        assert again["report"]["defaults"] == "passed", again["log"]
