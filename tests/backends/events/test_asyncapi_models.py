"""Code generators read the events backend's AsyncAPI documents: AsyncAPI Modelina (what `asyncapi generate
models python|typescript` runs, pinned and installed by .ci/setup-modelina.sh) makes a model of every message
payload of the RB-1's document, in Python and TypeScript, and of every golden document in Python.

Modelina refuses boolean subschemas, so the schema files leave out a member an event must not carry (the
in-memory contract marks it `false`); the files still mean what the runtime validates: the same good and bad
events, checked against the files as written. Skipped, saying why, when node or Modelina is missing.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest
from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

from tests.backends.events.test_events import BAD, GOOD, tree_of
from tests.conftest import REPO
from tests.runtime.rb1 import rb1_catalog, rb1_model
from tests.tools import missing, require

MODELINA = "5.10.1"
MODULES = REPO / ".cache" / "modelina" / "node_modules"
SCRIPT = Path(__file__).parent / "modelina_models.js"
GOLDEN = sorted((REPO / "tests" / "golden" / "cases").glob("*/expected/events/*/asyncapi.json"))


def _modelina() -> Path:
    require("node", "apt install nodejs")
    manifest = MODULES / "@asyncapi" / "modelina" / "package.json"
    if not manifest.is_file():
        missing(f"AsyncAPI Modelina is not installed in {MODULES.relative_to(REPO)} (bash .ci/setup-modelina.sh)")
    assert json.loads(manifest.read_text(encoding="utf-8"))["version"] == MODELINA
    return MODULES


def _models(language: str, document: Path) -> list[dict[str, Any]]:
    out = subprocess.run(
        ["node", str(SCRIPT), language, str(document)],
        env={**os.environ, "NODE_PATH": str(_modelina())},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    lines = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    models = lines[:-1]
    assert lines[-1] == {"generated": len(models)} and models
    return models


@pytest.fixture(scope="module")
def rb1_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("events") / "rb1"
    for path, data in tree_of(rb1_model()).items():
        (folder / path).parent.mkdir(parents=True, exist_ok=True)
        (folder / path).write_bytes(data)
    return folder


@pytest.mark.parametrize("language", ["python", "typescript"])
def test_modelina_makes_a_model_of_every_rb1_event(rb1_folder: Path, language: str) -> None:
    assert json.loads((rb1_folder / "asyncapi.json").read_text(encoding="utf-8"))["asyncapi"] == "3.1.0"
    models = _models(language, rb1_folder / "asyncapi.json")
    code = [m["code"] for m in models]
    # one model per event: each carries its affordance's name as a constant
    for spec in rb1_catalog().specs:
        if spec.affordance is not None:
            assert any(f"'{spec.affordance}'" in c for c in code), spec.key
    # a cancel event takes no payload, and its model has no such member to fill
    (cancel,) = [c for c in code if "'gotoCancel'" in c]
    assert "mission" in cancel and "payload" not in cancel
    if language == "python":
        for model in models:
            compile(model["code"], model["name"], "exec")  # what Modelina wrote is Python


@pytest.mark.parametrize("document", GOLDEN, ids=[p.parent.name for p in GOLDEN])
def test_modelina_makes_python_models_of_every_golden_document(document: Path) -> None:
    for model in _models("python", document):
        compile(model["code"], model["name"], "exec")


def _file_errors(folder: Path, key: str, event: Any) -> list[str]:
    catalog = rb1_catalog()
    resources = []
    for path in sorted((folder / "schemas").glob("*.schema.json")):
        document = json.loads(path.read_text(encoding="utf-8"))
        resources.append((document["$id"], Resource(contents=document, specification=DRAFT202012)))
    spec = next(s for s in catalog.specs if s.key == key)
    validator = Draft202012Validator({"$ref": catalog.uri(spec)}, registry=Registry().with_resources(resources))
    return [e.message for e in validator.iter_errors(event)]


def test_the_files_have_no_boolean_member_schema_and_mean_what_the_runtime_validates(rb1_folder: Path) -> None:
    texts = [p.read_text(encoding="utf-8") for p in (rb1_folder / "schemas").glob("*.schema.json")]
    assert not any('": false' in t.replace('"additionalProperties": false', "") for t in texts)
    for key, event in GOOD:
        assert _file_errors(rb1_folder, key, event) == [], (key, event)
    for key, event, _why in BAD:
        assert _file_errors(rb1_folder, key, event) != [], (key, event)
