"""The fast schema pass (jsonschema-rs) agrees with jsonschema on every document we can find: it only decides
whether jsonschema must look, so a document it calls valid must have no jsonschema error, and the reverse."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.frontend import conformance
from tests.conftest import REPO
from tests.wot_corpus import corpus

SCHEMAS = (conformance.TD_SCHEMA, conformance.TM_SCHEMA)


def _documents() -> list[tuple[str, Any]]:
    """Every JSON document of the repository's examples and tests, and of the WoT corpus when installed."""
    paths = [
        path
        for folder in ("examples", "tests")
        for path in sorted((REPO / folder).rglob("*.json"))
        if "expected" not in path.parts  # generated golden output: not documents anybody writes
    ]
    found = corpus()
    if found is not None:  # ../shared's, or the npm package's (under node_modules)
        paths += [f.path for f in found.files()]
    out = []
    for path in paths:
        try:
            data = json.loads(path.read_bytes())
        except ValueError:
            continue
        out.append((str(path.relative_to(REPO) if path.is_relative_to(REPO) else path), data))
    return out


def _agree(data: Any, schema: str) -> None:
    fast = conformance.schema_valid(data, schema)
    slow = not any(True for _ in conformance.validator(schema).iter_errors(data))
    assert fast is slow, (schema, data if len(json.dumps(data)) < 400 else "(large)")


def test_the_fast_pass_agrees_with_jsonschema_on_every_document() -> None:
    documents = _documents()
    assert len(documents) > 100
    verdicts = set()
    for _name, data in documents:
        for schema in SCHEMAS:
            _agree(data, schema)
            verdicts.add(conformance.schema_valid(data, schema))
    assert verdicts == {True, False}  # both answers occur: the comparison is not vacuous


BASE: dict[str, Any] = {
    "@context": "https://www.w3.org/2022/wot/td/v1.1",
    "title": "T",
    "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
    "security": "nosec_sc",
    "properties": {"p": {"type": "number", "forms": [{"href": "mqtt://h/p"}]}},
}


@pytest.mark.parametrize(
    ("pointer", "value"),
    [
        *[
            ("created", v)
            for v in (
                "2019-03-14T09:13:37Z",
                "2019-03-14T09:13:37.5+01:00",
                "2019-13-40T09:13:37Z",
                "2019-03-14 09:13:37",
                "yesterday",
                "2016-12-31T23:59:60Z",
            )
        ],
        *[("id", v) for v in ("urn:dev:ops:1", "https://example.com/t", "no scheme", "urn:a b", "ümlaut:x", "")],
        *[("base", v) for v in ("https://example.com/", "relative/path", "has space", "http://[::1]/", "é:x")],
        *[("properties/p/forms/0/href", v) for v in ("mqtt://h/p", "{?lat,long}", "/p{", "x y", "caf\u00e9")],
        *[
            ("titles/" + k, "x")
            for k in ("en", "en-GB-oed", "x-private", "zz-ZZZ-abcd", "english", "1234", "de-CH-1996")
        ],
        *[("properties/p/minimum", v) for v in (1, 1.5, "1", None, 2**70)],
    ],
)
def test_the_fast_pass_agrees_on_formats_patterns_and_types(pointer: str, value: Any) -> None:
    data = copy.deepcopy(BASE)
    *parents, last = pointer.split("/")
    node = data
    for key in parents:
        node = node.setdefault(key, {}) if not isinstance(node, list) else node[int(key)]
    node[last] = value
    for schema in SCHEMAS:
        fast = conformance.schema_valid(data, schema)
        slow = not any(True for _ in conformance.validator(schema).iter_errors(data))
        assert fast is None or fast is slow, (schema, pointer, value)


def test_an_invalid_document_still_gets_located_diagnostics(tmp_path: Path) -> None:
    """The fast pass never replaces the findings: a document it refuses is described by jsonschema."""
    data = copy.deepcopy(BASE)
    data["properties"]["p"]["forms"][0]["href"] = "x y"
    assert conformance.schema_valid(data, conformance.TD_SCHEMA) is False
    findings = conformance._schema_findings(data, conformance.TD_SCHEMA)
    assert findings and findings[0].pointer.startswith("/properties/p/forms/0/href")
