"""The AsyncAPI documents of the events backend, checked by the official AsyncAPI parser (@asyncapi/parser from
npm, pinned and installed by .ci/setup-wot.sh): 0 errors and 0 warnings, and the message payloads are checked
too (their schemaFormat, JSON Schema draft-07, is one the parser registers: a broken payload schema is
reported). The payloads also mean the same to a draft-07 validator as to the runtime's 2020-12 one.

Skipped, saying why, when node or the parser is missing (offline set-up).
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
from typing import Any

import pytest
from jsonschema import Draft7Validator  # type: ignore[import-untyped, unused-ignore]
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT7

from tests.backends.events.test_events import BAD, GOOD, tree_of
from tests.conftest import REPO
from tests.runtime.rb1 import rb1_catalog, rb1_model
from tests.tools import missing, require
from tests.wot_corpus import SETUP

PARSER = "3.6.3"
MODULES = REPO / ".cache" / "wot" / "node_modules"
CHECK = Path(__file__).parent / "asyncapi_check.js"


def _parser() -> Path:
    require("node", "apt install nodejs")
    manifest = MODULES / "@asyncapi" / "parser" / "package.json"
    if not manifest.is_file():
        missing(f"@asyncapi/parser is not installed in {MODULES} (run {SETUP})")
    assert json.loads(manifest.read_text(encoding="utf-8"))["version"] == PARSER
    return MODULES


def _parse(folder: Path) -> list[dict[str, Any]]:
    out = subprocess.run(
        ["node", str(CHECK), str(folder / "asyncapi.json")],
        env={**os.environ, "NODE_PATH": str(_parser())},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def _write(files: dict[str, bytes], folder: Path) -> Path:
    for path, data in files.items():
        (folder / path).parent.mkdir(parents=True, exist_ok=True)
        (folder / path).write_bytes(data)
    return folder


def test_the_asyncapi_parser_finds_no_error_or_warning_and_checks_the_payloads(tmp_path: Path) -> None:
    folder = _write(tree_of(rb1_model()), tmp_path / "rb1")
    lines = _parse(folder)
    assert lines[-1] == {"parsed": True}
    serious = [d for d in lines[:-1] if d["severity"] <= 1]  # 0 error, 1 warning (2 information, 3 hint)
    assert serious == []
    # AsyncAPI 3.1, the latest: not even the hint that a newer version exists
    assert lines[:-1] == []
    # the payloads are checked: a broken schema is reported where it is
    status = folder / "schemas" / "status.schema.json"
    broken = json.loads(status.read_text(encoding="utf-8"))
    broken["properties"]["payload"]["type"] = 5
    status.write_text(json.dumps(broken), encoding="utf-8")
    lines = _parse(folder)
    errors = [d for d in lines[:-1] if d["severity"] == 0]
    assert errors and lines[-1] == {"parsed": False}
    assert any(d["path"][:3] == ["components", "messages", "status"] for d in errors), errors


GOLDEN = sorted((REPO / "tests" / "golden" / "cases").glob("*/expected/events/*/asyncapi.json"))


@pytest.mark.parametrize("document", GOLDEN, ids=[p.parent.name for p in GOLDEN])
def test_every_golden_asyncapi_document_parses_without_error_or_warning(document: Path) -> None:
    lines = _parse(document.parent)
    assert lines[-1] == {"parsed": True} and [d for d in lines[:-1] if d["severity"] <= 1] == []


def _draft7_errors(key: str, event: Any) -> list[str]:
    """The event checked by a JSON Schema draft-07 validator (what AsyncAPI tools use), `$schema` aside."""
    catalog = rb1_catalog()
    resources = [
        (uri, Resource(contents={k: v for k, v in doc.items() if k != "$schema"}, specification=DRAFT7))
        for uri, doc in catalog.resources()
    ]
    spec = next(s for s in catalog.specs if s.key == key)
    validator = Draft7Validator({"$ref": catalog.uri(spec)}, registry=Registry().with_resources(resources))
    return [e.message for e in validator.iter_errors(event)]


@pytest.mark.parametrize(("key", "event"), GOOD, ids=[f"{k}-{i}" for i, (k, _) in enumerate(GOOD)])
def test_good_events_are_good_for_draft_07_too(key: str, event: Any) -> None:
    assert _draft7_errors(key, event) == []


@pytest.mark.parametrize(("key", "event", "why"), BAD, ids=[f"{k}-{i}" for i, (k, _, _) in enumerate(BAD)])
def test_bad_events_are_bad_for_draft_07_too(key: str, event: Any, why: str) -> None:
    assert _draft7_errors(key, event) != []
