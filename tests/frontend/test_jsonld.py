"""Offline JSON-LD: our own TD context must say exactly what the official W3C context says.

The official context is read here, and only here, as a test oracle (it may not ship with td2adaptor); the
differential test compares the canonical RDF (URDNA2015 N-Quads) of every valid and warning corpus TD
expanded with ours and with it.
"""

from __future__ import annotations

import hashlib
import json
import re
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.frontend import jsonld
from td2adaptor.frontend.bundled import load_schema
from td2adaptor.frontend.jsonsrc import JsonDocument, parse_json
from tests import wot_corpus
from tests.conftest import REPO

TD = "https://www.w3.org/2019/wot/td#"
ROSV = "https://td2adaptor.dev/ns/rosv#"


@pytest.fixture(scope="module")
def official_context() -> Any:
    raw = wot_corpus.official("td-context-v1.1.jsonld")  # only in ../shared: no registry package ships it
    # the oracle must be the W3C file the reference notes describe, not something edited since
    assert hashlib.sha256(raw).hexdigest().startswith("9298ddacce1d023e")
    return json.loads(raw)


@pytest.fixture(scope="module")
def corpus() -> list[Path]:
    """The valid and warning TDs of the corpus (../shared's 50, else the npm snapshot's 47)."""
    found = wot_corpus.require_corpus()
    files = [f.path for f in found.files("valid", "warn")]
    assert len(files) == found.count("valid", "warn")
    return files


def load(path: Path) -> JsonDocument:
    diags = Diagnostics()
    doc = parse_json(path.read_bytes(), path.name, diags)
    assert doc is not None, list(diags)
    return doc


def document(data: Any) -> JsonDocument:
    text = json.dumps(data)
    return JsonDocument("test.json", text, data)


def oracle_loader(official: Any) -> jsonld.OfflineLoader:
    return jsonld.OfflineLoader(
        {
            jsonld.TD_CONTEXT_V1: official,
            jsonld.TD_CONTEXT_V11: official,
            jsonld.ROSV_CONTEXT: load_schema("rosv-context-v1.jsonld"),
        }
    )


@pytest.fixture()
def no_network(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if anything tries pyld's default (network) loader or opens a connection."""
    from pyld import jsonld as pyld_jsonld

    def refuse_loader(url: str, options: Any = None) -> Any:
        pytest.fail(f"pyld's network document loader was called for {url}")

    def refuse_connect(self: socket.socket, address: Any) -> None:
        pytest.fail(f"network connection attempted to {address}")

    monkeypatch.setattr(pyld_jsonld, "_default_document_loader", refuse_loader)
    monkeypatch.setattr(socket.socket, "connect", refuse_connect)


# -- differential: our context vs the official one --


def test_same_rdf_as_official_context_on_corpus(corpus: list[Path], official_context: Any, no_network: None) -> None:
    differing = []
    for path in corpus:
        doc = load(path)
        ours_diags, theirs_diags = Diagnostics(), Diagnostics()
        ours = jsonld.to_rdf(doc, ours_diags, canonical=True)
        theirs = jsonld.to_rdf(doc, theirs_diags, canonical=True, loader=oracle_loader(official_context))
        assert theirs is not None and theirs.strip(), f"{path.name}: oracle produced no RDF"
        assert list(ours_diags) == list(theirs_diags) == [], path.name
        if ours != theirs:
            differing.append(path.name)
    assert differing == [], f"RDF differs from the official context's for: {', '.join(differing)}"


def _meaning(ctx: dict[str, Any], inherited: dict[str, str]) -> dict[str, Any]:
    """A context with every compact IRI written out, so two spellings of one definition compare equal."""
    prefixes = dict(inherited)
    prefixes.update(
        {k: v for k, v in ctx.items() if isinstance(v, str) and not k.startswith("@") and v.endswith(("#", "/"))}
    )

    def iri(value: Any) -> Any:
        if isinstance(value, str) and ":" in value and not value.startswith("@"):
            prefix, rest = value.split(":", 1)
            if prefix in prefixes:
                return prefixes[prefix] + rest
        return value

    out: dict[str, Any] = {}
    for key, value in ctx.items():
        if isinstance(value, dict):
            out[key] = {
                k: _meaning(v, prefixes) if k == "@context" else iri(v) if k in ("@id", "@type") else v
                for k, v in value.items()
            }
        else:
            out[key] = value if key.startswith("@") else iri(value)
    return out


def test_every_term_definition_means_the_same(official_context: Any) -> None:
    ours = _meaning(load_schema("td-context-1.1.jsonld")["@context"], {})
    theirs = _meaning(official_context["@context"], {})
    assert sorted(ours) == sorted(theirs)
    different = [term for term in theirs if ours[term] != theirs[term]]
    assert different == []


def test_our_context_is_not_a_copy(official_context: Any) -> None:
    ours = (REPO / "td2adaptor" / "frontend" / "schemas" / "td-context-1.1.jsonld").read_text(encoding="utf-8")
    assert json.loads(ours) != official_context  # same meaning, our own spelling (compact IRIs)
    assert '"td:title"' in ours and "Copyright" not in ours


# -- offline behaviour --


def test_unknown_remote_context_is_warned_not_fetched(no_network: None) -> None:
    url = "https://example.org/contexts/robot.jsonld"
    data = {
        "@context": [jsonld.TD_CONTEXT_V11, url, {"ex": "https://example.org/ns#"}],
        "title": "robot",
        "ex:color": "red",
        "robot:speed": 3,
    }
    diags = Diagnostics()
    expanded = jsonld.expand(document(data), diags)
    assert expanded is not None
    assert [(d.code, d.severity, d.pointer) for d in diags] == [("TD251", Severity.WARNING, "/@context/1")]
    assert url in diags.items[0].message
    node = expanded[0]
    assert node[TD + "title"] == [{"@value": "robot", "@language": "en"}]
    assert node["https://example.org/ns#color"] == [{"@value": "red"}]


def test_reference_context_url_is_not_served() -> None:
    data = {"@context": ["http://www.w3.org/ns/td", {"iot": "http://iotschema.org/"}], "title": "robotnik"}
    diags = Diagnostics()
    nquads = jsonld.to_rdf(document(data), diags)
    assert nquads == ""  # nothing the TD says is defined without the TD context
    (warning,) = diags.items
    assert warning.code == "TD251" and warning.pointer == "/@context/0"
    assert warning.hint is not None and jsonld.TD_CONTEXT_V11 in warning.hint


def test_each_unknown_context_warned_once_per_run() -> None:
    url = "https://example.org/ctx"
    data = {
        "@context": [jsonld.TD_CONTEXT_V11, url],
        "properties": {"p": {"@context": url, "type": "string"}},
    }
    for _ in range(2):  # also: pyld's cache must not hide the URL on the second run
        diags = Diagnostics()
        assert jsonld.expand(document(data), diags) is not None
        assert diags.codes() == ["TD251"]


def test_both_w3c_urls_serve_the_td_vocabulary(corpus: list[Path], no_network: None) -> None:
    data = json.loads(next(p for p in corpus if p.name == "simple.json").read_text(encoding="utf-8"))
    results = []
    for ctx in (jsonld.TD_CONTEXT_V11, jsonld.TD_CONTEXT_V1, [jsonld.TD_CONTEXT_V1, jsonld.TD_CONTEXT_V11]):
        diags = Diagnostics()
        results.append(jsonld.to_rdf(document({**data, "@context": ctx}), diags, canonical=True))
        assert len(diags) == 0
    assert results[0] and results[0] == results[1] == results[2]


def test_affordance_names_are_in_the_rdf(corpus: list[Path]) -> None:
    """pyld drops every td:name without a base option; the corpus has TDs with and without `id`."""
    checked = 0
    for path in corpus:
        doc = load(path)
        nquads = jsonld.to_rdf(doc, Diagnostics())
        assert nquads is not None
        for kind in ("properties", "actions", "events"):
            for name in doc.data.get(kind, {}):
                literal = re.escape(json.dumps(name, ensure_ascii=False))  # tagged if @language is set
                assert re.search(rf"<{TD}name> {literal}(@[A-Za-z-]+)? \.$", nquads, re.M), (path.name, name)
                checked += 1
    assert checked > 100
    assert "id" not in load(next(p for p in corpus if p.name == "noIdThing.json")).data


def test_rosv_terms_expand_to_the_binding_namespace() -> None:
    data = {
        "@context": [jsonld.TD_CONTEXT_V11, jsonld.ROSV_CONTEXT],
        "title": "rb1",
        "rosv:masterURI": "http://localhost:11311/",
        "properties": {
            "battery": {
                "type": "number",
                "forms": [
                    {
                        "href": "ros:///battery",
                        "rosv:interface": "topic",
                        "rosv:type": "sensor_msgs/msg/BatteryState",
                        "rosv:qos": {"depth": 5, "reliability": "best_effort"},
                    }
                ],
            }
        },
    }
    diags = Diagnostics()
    nquads = jsonld.to_rdf(document(data), diags)
    assert nquads is not None and len(diags) == 0
    assert f'<{ROSV}interface> "topic" .' in nquads
    assert f'<{ROSV}type> "sensor_msgs/msg/BatteryState" .' in nquads
    assert f"<{ROSV}masterURI> <http://localhost:11311/> ." in nquads
    qos = '"{\\"depth\\":5,\\"reliability\\":\\"best_effort\\"}"^^<http://www.w3.org/1999/02/22-rdf-syntax-ns#JSON>'
    assert f"<{ROSV}qos> {qos} ." in nquads
    assert f'<{TD}name> "battery" .' in nquads


# -- errors become diagnostics --


@pytest.mark.parametrize(
    ("context", "extra", "pointer"),
    [
        (5, {}, "/@context"),
        ([jsonld.TD_CONTEXT_V11, {"bad": 5}], {}, "/@context"),
        ({"@version": 1.0}, {}, "/@context"),
        (jsonld.TD_CONTEXT_V11, {"@id": 5}, ""),
        (jsonld.TD_CONTEXT_V11, {"@type": {"not": "a type"}}, ""),
        ([jsonld.TD_CONTEXT_V11, {"@vocab": 7}], {}, "/@context"),
    ],
)
def test_jsonld_syntax_errors_are_diagnostics(context: Any, extra: dict[str, Any], pointer: str) -> None:
    data = {"@context": context, "title": "x", **extra}
    for run in (jsonld.expand, jsonld.to_rdf):
        diags = Diagnostics()
        assert run(document(data), diags) is None
        (error,) = diags.items
        assert error.code == "TD252" and error.severity is Severity.ERROR, error
        assert error.pointer == pointer
        assert error.message.startswith("JSON-LD error [")


def test_relative_context_reference_is_named_as_written(no_network: None) -> None:
    data = {"@context": [jsonld.TD_CONTEXT_V11, "contexts/robot.jsonld"], "title": "x"}
    diags = Diagnostics()
    assert jsonld.expand(document(data), diags) is not None
    (warning,) = diags.items
    assert warning.code == "TD251" and warning.pointer == "/@context/1"
    assert "'contexts/robot.jsonld' (resolved to " in warning.message


def test_too_deep_and_non_object_documents_are_diagnostics() -> None:
    deep: dict[str, Any] = {"type": "string"}
    for _ in range(5000):
        deep = {"type": "object", "properties": {"a": deep}}
    data = {"@context": jsonld.TD_CONTEXT_V11, "title": "x", "actions": {"a": {"input": deep}}}
    diags = Diagnostics()
    assert jsonld.to_rdf(JsonDocument("deep.json", "", data), diags) is None
    assert diags.codes() == ["TD253"] and "nested too deeply" in diags.items[0].message
    for odd in ("https://example.org/td.jsonld", 5, None):
        diags = Diagnostics()
        assert jsonld.expand(document(odd), diags) is None
        assert diags.codes() == ["TD252"]


def test_codes_are_documented() -> None:
    assert set(jsonld.CODES) == {"TD251", "TD252", "TD253"}


def test_base_is_never_empty() -> None:
    assert jsonld.base_iri({"id": "urn:dev:wot:robotnik:client"}) == "urn:dev:wot:robotnik:client"
    odd: list[Any] = [{}, {"id": "relative/thing"}, {"id": 5}, [], None, {"id": ""}]
    for data in odd:
        assert jsonld.base_iri(data) == jsonld.DEFAULT_BASE


def test_canonical_output_is_stable_under_key_order() -> None:
    a = {
        "@context": jsonld.TD_CONTEXT_V11,
        "title": "t",
        "properties": {"p": {"type": "string", "forms": []}},
    }
    b = {
        "properties": {"p": {"forms": [], "type": "string"}},
        "title": "t",
        "@context": jsonld.TD_CONTEXT_V11,
    }
    assert jsonld.to_rdf(document(a), Diagnostics(), canonical=True) == jsonld.to_rdf(
        document(b), Diagnostics(), canonical=True
    )


def test_pyld_is_imported_lazily() -> None:
    code = "import sys, td2adaptor.frontend.jsonld; sys.exit('pyld' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], cwd=REPO, check=False).returncode == 0


# -- the compile's check: one affordance of each alike group first, the whole TD when that finds anything --


def _outcome(run: Any, data: Any) -> list[tuple[Any, ...]]:
    diags = Diagnostics()
    run(document(data), diags)
    return [(d.code, d.severity, d.message, d.pointer, d.hint) for d in diags]


def test_check_reports_what_expansion_reports_on_every_corpus_and_example_td() -> None:
    found = wot_corpus.corpus()
    paths = [f.path for f in found.files()] if found is not None else []
    paths += sorted(REPO.glob("examples/**/*.json")) + sorted(REPO.glob("tests/golden/cases/*/*.json"))
    paths += sorted(REPO.glob("tests/data/**/*.json"))
    assert len(paths) > 10
    for path in paths:
        try:
            data = json.loads(path.read_bytes())
        except ValueError:
            continue
        assert _outcome(jsonld.check, data) == _outcome(jsonld.expand, data), path


def _alike_td(n: int) -> dict[str, Any]:
    """A TD whose affordances differ only in ordinary strings (one group each for properties and actions)."""
    return {
        "@context": [jsonld.TD_CONTEXT_V11, jsonld.ROSV_CONTEXT],
        "title": "alike",
        "properties": {
            f"p{i}": {
                "type": "object",
                "title": f"property {i}",
                "properties": {"data": {"type": "number", "unit": f"u{i}"}},
                "forms": [{"href": f"ros:topic/p{i}", "op": ["readproperty"], "rosv:type": "std_msgs/msg/Float64"}],
            }
            for i in range(n)
        },
        "actions": {
            f"a{i}": {"input": {"type": "string"}, "forms": [{"href": f"ros:svc/a{i}", "rosv:name": f"/s{i}"}]}
            for i in range(n)
        },
    }


_EDITS: list[tuple[str, tuple[str, ...], Any]] = [
    (kind, path, value)
    for kind in ("properties", "actions")
    for path, value in [
        (("@direction",), "sideways"),
        (("@direction",), "ltr"),
        (("@id",), 5),
        (("@id",), "urn:x"),
        (("@type",), 5),
        (("@type",), "@json"),
        (("@type",), ["x", {"a": 1}]),
        (("type",), 5),
        (("type",), "number"),
        (("title",), 5),
        (("title",), {"@value": "x", "@language": 5}),
        (("title",), {"@value": "x", "@type": "relative"}),
        (("titles",), {"en": 5}),
        (("titles",), {"en": "x", "de": ["y", None]}),
        (("description",), ["a", {"@list": ["x"], "b": 1}]),
        (("forms", "0", "href"), ""),
        (("forms", "0", "href"), "@keywordlike"),
        (("forms", "0", "href"), 7),
        (("forms", "0", "rosv:qos"), {"depth": "x"}),
        (("@context",), "https://example.org/unknown.jsonld"),
        (("@context",), {"kind": "@type", "@base": "rel"}),
        (("kind",), "Thing"),
        (("@index",), 5),
        (("@reverse",), "x"),
        (("@value",), "x"),
        (("input", "type"), {"nested": "object"}),
        (("input", "@context"), {"@version": 1.0}),
        ((), "a bare string"),
        ((), 5),
        ((), ["x", {"@id": 5}]),
    ]
]


def _apply(td: dict[str, Any], kind: str, index: int, path: tuple[str, ...], value: Any) -> None:
    names = list(td[kind])
    name = names[index % len(names)]
    if not path:
        td[kind][name] = value
        return
    node: Any = td[kind][name]
    for step in path[:-1]:
        if isinstance(node, list) and step.isdigit() and int(step) < len(node):
            node = node[int(step)]
        elif isinstance(node, dict):
            node = node.setdefault(step, {})
        else:  # an earlier edit made the affordance (or a part on the path) something else
            return
    if isinstance(node, dict):
        node[path[-1]] = value


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(_EDITS), st.integers(0, 5)), max_size=3))
def test_check_reports_what_expansion_reports_when_one_affordance_differs(
    edits: list[tuple[tuple[str, tuple[str, ...], Any], int]],
) -> None:
    td = _alike_td(6)
    for (kind, path, value), index in edits:
        _apply(td, kind, index, path, value)
    assert _outcome(jsonld.check, td) == _outcome(jsonld.expand, td)


def test_check_expands_one_affordance_of_each_alike_group() -> None:
    reduced = jsonld._representatives(_alike_td(50))
    assert reduced is not None and list(reduced["properties"]) == ["p0"] and list(reduced["actions"]) == ["a0"]
    # an inline context anywhere: no grouping at all
    assert jsonld._representatives({**_alike_td(3), "@context": [jsonld.TD_CONTEXT_V11, {"x": "@id"}]}) is None
