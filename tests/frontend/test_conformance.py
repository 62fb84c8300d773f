"""TD 1.1 / Thing Model conformance: our schemas and extra checks, against the Playground corpus and the
official W3C schemas (used here, in tests only, as an oracle)."""

from __future__ import annotations

import copy
import hashlib
import json
import re
import subprocess
import sys
from functools import cache
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.frontend import conformance
from td2adaptor.frontend.bundled import load_schema
from td2adaptor.frontend.conformance import CODES, TD_SCHEMA, TM_SCHEMA, check_td, check_tm
from td2adaptor.frontend.jsonsrc import JsonDocument, load_path, parse_json
from tests import wot_corpus
from tests.conftest import EXAMPLE, REPO
from tests.wot_corpus import CorpusFile, corpus_files, params

TD_FOLDERS = ("valid", "invalid", "warn", "notValidYet")
# the manifest's `expected` for each corpus folder
EXPECTED = {
    "valid": "valid",
    "invalid": "invalid",
    "warn": "warning",
    "notValidYet": "not-valid-yet(valid per spec, playground cannot check)",
    "tm_valid": "valid-tm",
    "tm_invalid": "invalid-tm",
}
OFFICIAL_COLUMN = "official_1.1_schema_python_jsonschema"
SCHEMA_CODES = {f"TD10{i}" for i in range(7)}

# sha256 prefixes of the official files, as listed in ../shared/reference/wot.md §1
OFFICIAL_SHA256 = {
    "td-context-v1.jsonld": "9298ddacce1d023e",
    "td-context-v1.1.jsonld": "9298ddacce1d023e",
    "td-schema-v1.json": "cf2752835a40e232",
    "td-schema-v1.1.json": "905ff1138b35e1e9",
    "tm-schema-v1.1.json": "f5df99f473b05051",
}

# Needs the Thing Model it links to (a network fetch): offline it cannot be found to contradict it.
NEEDS_LINKED_TM = "invalid/usingTM.json"
# Needs tm:extends resolution of an unreachable parent (handled by the TM instantiation stage).
NEEDS_PARENT_TM = "tm_invalid/unavailableParent.json"

TD_FILES = corpus_files(*TD_FOLDERS)
TM_FILES = corpus_files("tm_valid", "tm_invalid")


def _run(check: Any, path: Path) -> tuple[JsonDocument | None, Diagnostics]:
    """Loader + check, exactly as the CLI runs them."""
    diags = Diagnostics()
    doc = load_path(str(path), diags)
    if doc is not None:
        check(doc, diags)
    return doc, diags


def _doc(data: Any) -> tuple[JsonDocument, Diagnostics]:
    diags = Diagnostics()
    doc = parse_json(json.dumps(data, indent=2), "t.json", diags)
    assert doc is not None and not diags.items
    return doc, diags


def td_diags(data: Any) -> list[Diagnostic]:
    doc, diags = _doc(data)
    check_td(doc, diags)
    return list(diags)


def tm_diags(data: Any) -> list[Diagnostic]:
    doc, diags = _doc(data)
    check_tm(doc, diags)
    return list(diags)


def only(diags: list[Diagnostic], code: str) -> list[Diagnostic]:
    return [d for d in diags if d.code == code]


BASE: dict[str, Any] = {
    "@context": "https://www.w3.org/2022/wot/td/v1.1",
    "title": "Lamp",
    "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
    "security": "nosec_sc",
    "properties": {
        "on": {"type": "boolean", "forms": [{"href": "https://lamp.example.com/on"}]},
    },
    "actions": {"toggle": {"forms": [{"href": "https://lamp.example.com/toggle"}]}},
}


def td(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    data.update(changes)
    return data


TM_BASE: dict[str, Any] = {
    "@context": ["https://www.w3.org/2022/wot/td/v1.1"],
    "@type": "tm:ThingModel",
    "title": "Lamp model {{N}}",
    "properties": {"status": {"type": "string"}},
    "actions": {"toggle": {}},
}


def tm(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(TM_BASE)
    data.update(changes)
    return data


# ---------------------------------------------------------------------------------------------------------
# the reference material itself


@pytest.mark.parametrize("name", sorted(OFFICIAL_SHA256))
def test_official_files_are_the_pinned_versions(name: str) -> None:
    # from ../shared byte for byte; from npm with its CRLF line ends made LF (so: otherwise the same bytes)
    digest = hashlib.sha256(wot_corpus.official(name)).hexdigest()
    assert digest.startswith(OFFICIAL_SHA256[name]), (name, wot_corpus.official_source(name))


def test_manifest_covers_the_whole_corpus() -> None:
    manifest = wot_corpus.manifest()
    corpus = wot_corpus.require_shared_corpus("manifest.csv describes its files")
    counts: dict[str, int] = {}
    for row in manifest:
        counts[row["path"].split("/")[0]] = counts.get(row["path"].split("/")[0], 0) + 1
    assert counts == {
        "valid": 44,
        "invalid": 23,
        "warn": 6,
        "notValidYet": 6,
        "tm_valid": 13,
        "tm_invalid": 6,
    }
    on_disk = {f.rel for f in corpus.files()}
    assert on_disk == {row["path"] for row in manifest}
    # the tests below take a file's expected verdict from its folder
    assert all(row["expected"] == EXPECTED[row["path"].split("/")[0]] for row in manifest)


def test_corpus_has_the_pinned_contents() -> None:
    corpus = wot_corpus.require_corpus()
    for kind in wot_corpus.KINDS:
        assert len(corpus.files(kind)) == corpus.count(kind), (corpus.label, kind)


def test_npm_data_differs_from_shared_only_where_listed() -> None:
    """The npm packages against ../shared/wot: the schemas are the W3C files (CRLF line ends), the corpus is an
    older snapshot whose differences wot_corpus lists (the tests that need the exact files skip on it)."""
    missing = [n for n in wot_corpus.NPM_VERSIONS if wot_corpus.npm_package(n) is None]
    if not (wot_corpus.SHARED_WOT / "playground").is_dir() or missing:
        pytest.skip(f"needs both ../shared/wot and the pinned npm packages ({wot_corpus.SETUP})")
    for name, (package_name, inner) in wot_corpus.OFFICIAL_IN_NPM.items():
        path = wot_corpus.npm_package(package_name)
        assert path is not None
        raw = (path / inner).read_bytes()
        assert raw.replace(b"\r\n", b"\n") == (wot_corpus.SHARED_WOT / "official" / name).read_bytes(), name
    playground = wot_corpus.npm_package(wot_corpus.PLAYGROUND_PACKAGE)
    assert playground is not None
    shared = wot_corpus.SHARED_WOT / "playground"
    npm = {f"{k}/{p.name}": p for k, d in wot_corpus.NPM_FOLDERS.items() for p in (playground / d).glob("*.json")}
    ours = {f"{kind}/{p.name}": p for kind in wot_corpus.KINDS for p in (shared / kind).glob("*.json")}
    assert set(ours) - set(npm) == wot_corpus.NPM_MISSING
    assert set(npm) - set(ours) == wot_corpus.NPM_EXTRA
    assert {k: len([r for r in npm if r.startswith(k + "/")]) for k in wot_corpus.KINDS} == wot_corpus.COUNTS["npm"]

    def data(path: Path) -> Any:  # key order and duplicate keys kept
        return json.loads(path.read_bytes(), object_pairs_hook=lambda pairs: ("object", pairs))

    assert {rel for rel in set(npm) & set(ours) if data(npm[rel]) != data(ours[rel])} == wot_corpus.NPM_DIFFERENT


# ---------------------------------------------------------------------------------------------------------
# differential tests over the Playground corpus (../shared's, else the npm snapshot)


@pytest.mark.parametrize("f", params(TD_FILES))
def test_corpus_td_verdicts(f: CorpusFile) -> None:
    doc, diags = _run(check_td, f.path)
    assert doc is not None
    errors = [f"{d.code} {d.pointer}: {d.message}" for d in diags.errors()]
    if f.rel == NEEDS_LINKED_TM:
        # The Playground rejects it only after fetching the TM it links to (network); offline it must pass
        # our checks. The "linked TM not fetched" warning is the Thing Model stage's job, not this module's.
        assert errors == []
    elif f.kind == "invalid":
        assert errors, "an invalid TD was accepted"
    else:  # valid, warning, not-valid-yet (valid per spec)
        assert errors == []


@cache
def _official(name: str) -> Any:
    from jsonschema import Draft7Validator, FormatChecker  # type: ignore[import-untyped, unused-ignore]

    return Draft7Validator(wot_corpus.official_json(name), format_checker=FormatChecker())


def _official_errors(name: str, data: Any) -> list[str]:
    """Pointers of the official schema's (best-match) errors."""
    from jsonschema.exceptions import best_match  # type: ignore[import-untyped, unused-ignore]

    out = []
    for err in _official(name).iter_errors(data):
        leaf = best_match([err])
        out.append("".join(f"/{t}" for t in leaf.absolute_path))
    return out


def _official_schema(rel: str) -> str:
    return "tm-schema-v1.1.json" if rel.startswith("tm_") else "td-schema-v1.1.json"


@pytest.mark.parametrize("f", params(corpus_files()))
def test_official_schema_rejection_implies_ours(f: CorpusFile) -> None:
    """Oracle: what the official W3C schema rejects, our schema rejects too, at the same place or deeper."""
    is_tm = f.kind.startswith("tm_")
    data = json.loads(f.path.read_text(encoding="utf-8"))
    official = _official_errors(_official_schema(f.rel), data)
    ours = (tm_diags if is_tm else td_diags)(data)
    ours_schema = [d for d in ours if d.code in SCHEMA_CODES and d.severity is Severity.ERROR]
    if official:
        assert ours_schema, f"official schema rejects at {official}, ours accepts"
        for pointer in official:
            assert any(d.pointer == pointer or d.pointer.startswith(pointer + "/") for d in ours_schema), pointer


def test_manifest_records_the_official_schema_verdicts() -> None:
    manifest = wot_corpus.manifest()
    corpus = wot_corpus.require_shared_corpus("manifest.csv records its files' official-schema verdicts")
    wrong = []
    for row in manifest:
        data = json.loads(corpus.file(row["path"]).read_text(encoding="utf-8"))
        official = _official_errors(_official_schema(row["path"]), data)
        if (row[OFFICIAL_COLUMN] == "pass") != (not official):
            wrong.append(f"{row['path']}: manifest {row[OFFICIAL_COLUMN]}, official schema errors at {official}")
    assert wrong == []


@pytest.mark.parametrize("f", params([f for f in TM_FILES if f.kind == "tm_valid"]))
def test_corpus_valid_thing_models_pass(f: CorpusFile) -> None:
    doc, diags = _run(check_tm, f.path)
    assert doc is not None
    assert [f"{d.code} {d.pointer}: {d.message}" for d in diags.errors()] == []


@pytest.mark.parametrize("f", params([f for f in TM_FILES if f.kind == "tm_invalid"]))
def test_corpus_invalid_thing_models(f: CorpusFile) -> None:
    doc, diags = _run(check_tm, f.path)
    assert doc is not None
    if f.rel == NEEDS_PARENT_TM:
        # Invalid only because its tm:extends parent cannot be loaded: that is checked when the model is
        # resolved/instantiated (another stage), not by the offline model conformance check.
        assert not diags.has_errors
    else:
        # the official TM schema rejects it (what manifest.csv records: test_manifest_records_...)
        assert _official_errors("tm-schema-v1.1.json", json.loads(f.path.read_text(encoding="utf-8")))
        assert diags.has_errors


def test_corpus_messages_are_one_line_and_located() -> None:
    for f in wot_corpus.require_corpus().files():
        check = check_tm if f.kind.startswith("tm_") else check_td
        doc, diags = _run(check, f.path)
        assert doc is not None
        for d in diags:
            assert "\n" not in d.message and len(d.message) <= 200
            assert d.code in CODES or d.code == "TD003"
            assert doc.locate(d).line is not None


# ---------------------------------------------------------------------------------------------------------
# the reference system's robot TD: its three official-schema defects, at precise pointers


ROBOT: dict[str, Any] = {
    "id": "urn:dev:wot:robotnik:client",
    "lastModified": "1552589098",
    "links": [{"rel": "about"}],
    "security": ["nosec_sc"],
    "ros:masterURI": "http://localhost:11311/",
    "version": {"instance": "1.0.0"},
    "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
    "title": "robotnik",
    "created": "1552554817",
    "@context": [
        "http://www.w3.org/ns/td",
        {"iot": "http://iotschema.org", "robot": "http://robot.schema.org"},
    ],
    "@type": "Thing",
    "properties": {
        "availability": {
            "type": "object",
            "properties": {"level:": {"type": "number"}},
            "readOnly": True,
            "writeOnly": False,
            "observable": True,
            "forms": [
                {
                    "href": "",
                    "contentType": "application/xml",
                    "op": ["readproperty", "observeproperty"],
                    "subprotocol": "ros",
                    "ros:TopicName": "/#robotName/robot_local_control/state",
                }
            ],
        }
    },
    "actions": {
        "gotoRun": {
            "input": {"type": "object", "properties": {"x": {"type": "number"}}},
            "forms": [{"href": "", "op": ["invokeaction"], "subprotocol": "ros", "ros:serviceName": "/x"}],
        }
    },
}


def test_reference_robot_td_defects() -> None:
    errors = [d for d in td_diags(ROBOT) if d.severity is Severity.ERROR]
    by_pointer = {d.pointer: d for d in errors}
    assert set(by_pointer) == {"/@context/0", "/created", "/links/0"}
    assert by_pointer["/@context/0"].code == "TD106"
    assert "http://www.w3.org/ns/td" in by_pointer["/@context/0"].message
    assert "v1.1" in (by_pointer["/@context/0"].hint or "")
    assert by_pointer["/created"].code == "TD104" and "date-time" in by_pointer["/created"].message
    assert "2019-03-14T09:13:37Z" in (by_pointer["/created"].hint or "")
    assert by_pointer["/links/0"].code == "TD101" and "'href'" in by_pointer["/links/0"].message


def test_reference_dialect_example_has_exactly_the_three_schema_defects() -> None:
    doc, diags = _run(check_td, EXAMPLE / "td.reference-dialect.json")
    assert doc is not None
    assert sorted((d.code, d.pointer) for d in diags.errors()) == [
        ("TD101", "/links/0"),
        ("TD104", "/created"),
        ("TD106", "/@context/0"),
    ]


def test_subprotocol_is_free_text_in_td_1_1() -> None:
    data = td()
    data["properties"]["on"]["forms"][0]["subprotocol"] = "ros"
    assert td_diags(data) == []


# ---------------------------------------------------------------------------------------------------------
# schema behaviour


def test_minimal_td_is_clean() -> None:
    assert td_diags(BASE) == []


@pytest.mark.parametrize(
    "context",
    [
        "https://www.w3.org/2019/wot/td/v1",
        ["https://www.w3.org/2019/wot/td/v1"],
        [
            "https://www.w3.org/2019/wot/td/v1",
            "https://www.w3.org/2022/wot/td/v1.1",
            {"saref": "https://w3id.org/saref#"},
        ],
        ["https://www.w3.org/2022/wot/td/v1.1", {"@language": "de"}, "https://example.com/ctx"],
    ],
)
def test_td_1_0_and_1_1_context_forms_accepted(context: Any) -> None:
    assert td_diags(td(**{"@context": context})) == []


@pytest.mark.parametrize(
    ("context", "pointer"),
    [
        ("http://www.w3.org/ns/td", "/@context"),
        (["https://example.com/ctx", "https://www.w3.org/2022/wot/td/v1.1"], "/@context/0"),
        (["https://www.w3.org/2022/wot/td/v1.1", "https://www.w3.org/2019/wot/td/v1"], "/@context/1"),
        (["https://www.w3.org/2022/wot/td/v1.1", {"x": 1}], "/@context/1/x"),
        ([], "/@context"),
    ],
)
def test_bad_contexts_rejected_at_the_offending_entry(context: Any, pointer: str) -> None:
    errors = [d for d in td_diags(td(**{"@context": context})) if d.severity is Severity.ERROR]
    assert [d.pointer for d in errors] == [pointer]


def test_all_schema_errors_reported_once_each_in_document_order() -> None:
    data = td(created="yesterday", support="not a uri")
    del data["title"]
    data["properties"]["on"]["type"] = "bool"
    data["properties"]["on"]["forms"][0]["op"] = ["readproperty", "readproperty", "invokeaction"]
    data["actions"]["toggle"]["forms"] = []
    diags = td_diags(data)
    pointers = [d.pointer for d in diags]
    assert pointers == [
        "",
        "/properties/on/type",
        "/properties/on/forms/0/op/2",
        "/actions/toggle/forms",
        "/created",
        "/support",
    ]
    assert len(set((d.pointer, d.message) for d in diags)) == len(diags)
    assert all(d.severity is Severity.ERROR and d.code in SCHEMA_CODES for d in diags)


def test_enum_errors_suggest_the_intended_value() -> None:
    data = td()
    data["securityDefinitions"] = {"b": {"scheme": "basic", "in": "Header"}}
    data["security"] = "b"
    [d] = td_diags(data)
    assert (d.code, d.pointer) == ("TD103", "/securityDefinitions/b/in")
    assert d.hint == "did you mean 'header'?"


def test_security_scheme_members_checked_by_scheme() -> None:
    data = td()
    data["securityDefinitions"] = {
        "d": {"scheme": "digest", "qop": "none"},
        "c": {"scheme": "combo", "oneOf": ["d", "x"], "allOf": ["d", "x"]},
        "a": {"scheme": "auto", "name": "n"},
        "e": {"scheme": "ace:ACESecurityScheme", "ace:as": "coaps://as.example.com/token"},
        "u": {"scheme": "magic"},
    }
    data["security"] = "d"
    errors = {d.pointer: d for d in td_diags(data) if d.code in SCHEMA_CODES}
    assert set(errors) == {
        "/securityDefinitions/d/qop",
        "/securityDefinitions/c",
        "/securityDefinitions/a",
        "/securityDefinitions/u/scheme",
    }
    assert "exactly one of 'oneOf' or 'allOf'" in errors["/securityDefinitions/c"].message
    assert "must not have 'name'" in errors["/securityDefinitions/a"].message


def test_a_thing_model_is_not_a_td() -> None:
    data = td(**{"@type": ["Thing", "tm:ThingModel"]})
    [d] = td_diags(data)
    assert d.pointer == "/@type" and "Thing Model" in d.message


def test_links_tm_extends_and_sizes() -> None:
    data = td(
        links=[
            {"rel": "tm:extends", "href": "https://example.com/model"},
            {"rel": "icon", "href": "https://example.com/i.png", "sizes": "16x16 32x32"},
            {"rel": "alternate", "href": "https://example.com/a", "sizes": "16x16"},
            {"rel": "icon", "href": "https://example.com/i.png", "sizes": "large"},
            {"href": "https://example.com/doc", "hreflang": ["en", "not a tag"]},
        ]
    )
    assert [d.pointer for d in td_diags(data)] == [
        "/links/0/rel",
        "/links/2",
        "/links/3/sizes",
        "/links/4/hreflang/1",
    ]


@pytest.mark.parametrize(
    ("value", "ok"),
    [
        ("2019-03-14T09:13:37Z", True),
        ("2019-03-14t09:13:37.123+01:00", True),
        ("2016-12-31T23:59:60Z", True),
        ("2020-02-29T00:00:00Z", True),
        ("2019-02-29T00:00:00Z", False),
        ("2019-13-01T00:00:00Z", False),
        ("2019-03-14 09:13:37Z", False),
        ("2019-03-14T09:13:37", False),
        ("2019-03-14T24:00:00Z", False),
        ("1552554817", False),
    ],
)
def test_date_time_format_is_checked(value: str, ok: bool) -> None:
    diags = td_diags(td(modified=value))
    assert (diags == []) is ok
    if not ok:
        assert [(d.code, d.pointer) for d in diags] == [("TD104", "/modified")]


@pytest.mark.parametrize(
    ("href", "ok"),
    [
        ("", True),
        ("properties/on", True),
        ("coaps://lamp.example.com/{p}/{d}/toggle{?a,b}", True),
        ("https://example.com/{secClientID}/status/{+path}{#frag}{?list*,n:3}", True),
        ("https://example.com/ünïcode", True),
        ("https://example.com/a b", False),
        ("https://example.com/{bad name}", False),
        ("https://example.com/{}", False),
        ("https://example.com/{open", False),
        ("https://example.com/%zz", False),
    ],
)
def test_href_is_an_iri_reference_or_uri_template(href: str, ok: bool) -> None:
    data = td()
    data["properties"]["on"]["forms"][0]["href"] = href
    diags = td_diags(data)
    assert (diags == []) is ok
    if not ok:
        assert [(d.code, d.pointer) for d in diags] == [("TD104", "/properties/on/forms/0/href")]


def test_iri_reference_format_is_checked_on_links_and_base() -> None:
    data = td(base="http://exa mple.com/", links=[{"href": "<https://example.com>"}], id="not an absolute uri")
    assert sorted(d.pointer for d in td_diags(data)) == ["/base", "/id", "/links/0/href"]


def test_items_may_be_a_schema_or_a_list_of_schemas() -> None:
    data = td()
    data["properties"]["on"] = {
        "type": "array",
        "items": [{"type": "integer"}, {"type": "strin"}],
        "forms": [{"href": "x"}],
    }
    [d] = td_diags(data)
    assert d.pointer == "/properties/on/items/1/type"
    data["properties"]["on"]["items"] = {"type": "number", "minimum": "0"}
    [d] = td_diags(data)
    assert (d.code, d.pointer) == ("TD102", "/properties/on/items/minimum")


# ---------------------------------------------------------------------------------------------------------
# extra checks


def test_undefined_security_names_are_errors_at_each_use() -> None:
    data = td(security=["nosec_sc", "basic"])
    data["actions"]["toggle"]["forms"][0]["security"] = "nosec_sc"
    data["properties"]["on"]["forms"][0]["security"] = ["nosec-sc"]
    found = only(td_diags(data), "TD110")
    assert [(d.pointer, d.severity) for d in found] == [
        ("/security/1", Severity.ERROR),
        ("/properties/on/forms/0/security/0", Severity.ERROR),
    ]
    assert found[1].hint == "did you mean 'nosec_sc'?"


def test_combo_references_checked() -> None:
    data = td()
    data["securityDefinitions"]["c"] = {"scheme": "combo", "allOf": ["nosec_sc", "missing"]}
    data["securityDefinitions"]["self"] = {"scheme": "combo", "oneOf": ["self", "nosec_sc"]}
    found = only(td_diags(data), "TD111")
    assert [d.pointer for d in found] == [
        "/securityDefinitions/c/allOf/1",
        "/securityDefinitions/self/oneOf/0",
    ]


def test_at_most_one_type_link() -> None:
    one = td(links=[{"rel": "type", "href": "https://example.com/m1"}, {"rel": "item", "href": "https://e.com"}])
    assert td_diags(one) == []
    two = td(links=[{"rel": "type", "href": "https://example.com/m1"}, {"rel": "type", "href": "https://e.com/m"}])
    [d] = td_diags(two)
    assert (d.code, d.severity, d.pointer) == ("TD113", Severity.ERROR, "/links/1/rel")


def test_additional_response_schema_must_be_defined() -> None:
    data = td(schemaDefinitions={"error": {"type": "string"}})
    data["actions"]["toggle"]["forms"][0]["additionalResponses"] = [
        {"success": False, "schema": "error"},
        {"success": False, "schema": "eror"},
    ]
    [d] = td_diags(data)
    assert (d.code, d.pointer) == ("TD112", "/actions/toggle/forms/0/additionalResponses/1/schema")
    assert d.hint == "did you mean 'error'?"


def test_enum_with_const_warns() -> None:
    data = td()
    data["properties"]["on"].update(enum=[True, False], const=True)
    [d] = td_diags(data)
    assert (d.code, d.severity, d.pointer) == ("TD120", Severity.WARNING, "/properties/on")


def test_object_without_properties_and_array_without_items_warn_also_when_nested() -> None:
    data = td()
    data["actions"]["toggle"]["input"] = {
        "type": "object",
        "properties": {"list": {"type": "array"}, "blob": {"type": "object"}},
    }
    data["actions"]["toggle"]["output"] = {"type": "object", "oneOf": [{"type": "object", "properties": {}}]}
    found = [(d.code, d.pointer) for d in td_diags(data)]
    assert found == [
        ("TD122", "/actions/toggle/input/properties/list"),
        ("TD121", "/actions/toggle/input/properties/blob"),
    ]


def test_read_only_and_write_only_contradictions_warn() -> None:
    data = td()
    data["properties"]["on"].update(readOnly=True, writeOnly=True)
    data["properties"]["ro"] = {
        "readOnly": True,
        "forms": [{"href": "x", "op": ["readproperty", "writeproperty"]}],
    }
    found = [(d.code, d.severity, d.pointer) for d in td_diags(data)]
    assert found == [
        ("TD123", Severity.WARNING, "/properties/on/writeOnly"),
        ("TD124", Severity.WARNING, "/properties/ro/forms/0/op/1"),
    ]


def test_multi_language_maps_must_agree() -> None:
    data = td(titles={"en": "Lamp", "de": "Lampe"}, descriptions={"en": "A lamp", "de": "Eine Lampe"})
    data["properties"]["on"]["titles"] = {"en": "On", "DE": "An"}  # tags are case-insensitive
    assert td_diags(data) == []
    data["actions"]["toggle"]["titles"] = {"en": "Toggle", "fr": "Basculer"}
    [d] = td_diags(data)
    assert (d.code, d.severity, d.pointer) == ("TD125", Severity.WARNING, "/actions/toggle/titles")
    assert "lacks de" in d.message and "adds fr" in d.message


def test_malformed_language_tags_warn() -> None:
    data = td(titles={"en": "Lamp", "en_US": "Lamp", "zh-Hant": "燈", "x-klingon": "?", "de-CH-1996": "Lampe"})
    found = [(d.code, d.pointer) for d in td_diags(data)]
    assert found == [("TD126", "/titles/en_US")]


def test_apikey_in_uri_needs_a_template_variable_distinct_from_uri_variables() -> None:
    data = td()
    data["securityDefinitions"]["key"] = {"scheme": "apikey", "in": "uri", "name": "apiKey"}
    data["properties"]["on"]["forms"][0].update(href="https://lamp.example.com/{apiKey}/on", security="key")
    assert td_diags(data) == []
    data["actions"]["toggle"]["forms"][0]["security"] = ["key"]
    data["actions"]["toggle"]["uriVariables"] = {"apiKey": {"type": "string"}}
    found = [(d.code, d.pointer) for d in td_diags(data)]
    assert found == [  # document order: forms come before uriVariables in this TD
        ("TD127", "/actions/toggle/forms/0/href"),
        ("TD128", "/actions/toggle/uriVariables/apiKey"),
    ]


def test_extra_checks_survive_malformed_documents() -> None:
    weird: list[Any] = [
        [],
        "x",
        {"properties": [], "actions": {"a": "b"}, "forms": "x", "links": {}, "security": 3},
        {
            "securityDefinitions": {"c": {"scheme": "combo", "allOf": "x"}},
            "properties": {"p": {"forms": [1]}},
        },
        {"titles": [], "properties": {"p": {"type": "object", "items": 3, "oneOf": {}}}},
    ]
    for data in weird:
        assert any(d.severity is Severity.ERROR for d in td_diags(data))


# ---------------------------------------------------------------------------------------------------------
# Thing Models


def test_thing_model_basics() -> None:
    assert tm_diags(TM_BASE) == []
    assert [d.pointer for d in tm_diags(tm(**{"@type": "Thing"}))] == ["/@type"]


def test_thing_model_placeholders() -> None:
    data = tm(version="{{VERSION}}", base="mqtt://{{BROKER}}")
    data["properties"]["temp"] = {
        "type": "{{TYPE}}",
        "maximum": "{{MAX}}",
        "observable": "{{OBS}}",
        "forms": [{"op": "{{OP}}", "href": "mqtt://{{BROKER}}/t"}],
    }
    data["securityDefinitions"] = {"sc": {"scheme": "{{SCHEME}}", "in": "{{IN}}"}}
    assert tm_diags(data) == []
    data["properties"]["temp"]["maximum"] = "{MAX}"
    data["properties"]["{{NAME}}"] = {"type": "string"}
    assert sorted(d.pointer for d in tm_diags(data)) == ["/properties", "/properties/temp/maximum"]


def test_thing_model_version_must_not_have_instance() -> None:
    [d] = tm_diags(tm(version={"model": "1.0.0", "instance": "1.0.0"}))
    assert (d.pointer, d.message) == ("/version", "a Thing Model's version must not contain 'instance'")


def test_alternatives_are_narrowed_to_the_intended_branch() -> None:
    """A TM value may be a placeholder or a TD value; a typo is reported against the TD value, not as
    'matches none of the alternatives'."""
    data = tm()
    data["properties"]["status"]["type"] = "strng"
    data["actions"]["toggle"]["safe"] = "yes"
    found = {d.pointer: d for d in tm_diags(data)}
    assert set(found) == {"/properties/status/type", "/actions/toggle/safe"}
    assert found["/properties/status/type"].code == "TD103"
    assert found["/properties/status/type"].hint == (
        "did you mean 'string'?; a placeholder such as {{NAME}} is also accepted here"
    )
    assert found["/actions/toggle/safe"].code == "TD102"
    assert found["/actions/toggle/safe"].message == 'expected boolean, found string "yes"'
    assert found["/actions/toggle/safe"].hint == "a placeholder such as {{NAME}} is also accepted here"


def test_tm_optional_must_resolve_to_whole_affordances() -> None:
    assert tm_diags(tm(**{"tm:optional": ["/properties/status", "/actions/toggle"]})) == []
    found = tm_diags(tm(**{"tm:optional": ["/properties/satus", "/events/status", "/properties/status/type"]}))
    assert [(d.code, d.pointer) for d in found] == [
        ("TD114", "/tm:optional/0"),
        ("TD114", "/tm:optional/1"),
        ("TD104", "/tm:optional/2"),
    ]
    assert found[0].hint == "did you mean '/properties/status'?"


def test_thing_model_tm_ref_format() -> None:
    data = tm()
    data["properties"]["status"]["tm:ref"] = "https://example.com/m.tm.jsonld#/properties/s"
    assert tm_diags(data) == []
    data["properties"]["status"]["tm:ref"] = "https://example.com/a model#/x"
    assert [d.pointer for d in tm_diags(data)] == ["/properties/status/tm:ref"]


# ---------------------------------------------------------------------------------------------------------
# the module's own contracts


def test_codes_are_documented_and_in_range() -> None:
    assert all(re.fullmatch(r"TD1\d\d", code) for code in CODES)
    source = Path(conformance.__file__).read_text(encoding="utf-8")
    used = set(re.findall(r'"(TD1\d\d)"', source))
    assert used == set(CODES)


def test_our_schemas_are_valid_2020_12_schemas_of_our_own() -> None:
    from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

    for name in (TD_SCHEMA, TM_SCHEMA):
        schema = load_schema(name)
        Draft202012Validator.check_schema(schema)
        assert schema["$id"].startswith("https://td2adaptor.dev/")
        assert (REPO / "td2adaptor" / "frontend" / "schemas" / name).is_file()


def test_validators_are_compiled_once() -> None:
    assert conformance.validator(TD_SCHEMA) is conformance.validator(TD_SCHEMA)
    assert conformance.validator(TM_SCHEMA) is not conformance.validator(TD_SCHEMA)


def test_importing_does_not_import_jsonschema() -> None:
    code = "import sys, td2adaptor.frontend.conformance, td2adaptor.frontend.terms; print('jsonschema' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert out.stdout.strip() == "False"
