"""Unknown-term checking: misspelled and misplaced TD terms, undeclared prefixes, suspicious member names."""

from __future__ import annotations

import copy
import json
from typing import Any

import pytest

from td2adaptor.diagnostics import Diagnostic, Diagnostics, Severity
from td2adaptor.frontend.jsonsrc import JsonDocument, load_path, parse_json
from td2adaptor.frontend.terms import CODES, check_terms
from tests import wot_corpus

BASE: dict[str, Any] = {
    "@context": "https://www.w3.org/2022/wot/td/v1.1",
    "title": "Lamp",
    "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
    "security": "nosec_sc",
    "properties": {"on": {"type": "boolean", "forms": [{"href": "https://lamp.example.com/on"}]}},
    "actions": {"toggle": {"forms": [{"href": "https://lamp.example.com/toggle"}]}},
}


def td(**changes: Any) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    data.update(changes)
    return data


def _doc(data: Any) -> JsonDocument:
    diags = Diagnostics()
    doc = parse_json(json.dumps(data, indent=2), "t.json", diags)
    assert doc is not None and not diags.items
    return doc


def terms(data: Any) -> list[Diagnostic]:
    doc = _doc(data)
    diags = Diagnostics()
    check_terms(doc, diags)
    assert all(d.severity is Severity.WARNING and d.code in CODES for d in diags)
    return [doc.locate(d) for d in diags]


def test_clean_td_has_no_findings() -> None:
    assert terms(BASE) == []


def test_misspelled_term_gets_did_you_mean_and_points_at_the_key() -> None:
    [d] = terms(td(titel="Lamp"))
    assert (d.code, d.pointer) == ("TD201", "/titel")
    assert d.hint == "did you mean 'title'?"
    assert "titel" in d.message
    text = _doc(td(titel="Lamp")).text
    line = text.splitlines()[d.line - 1] if d.line else ""
    assert line[(d.col or 1) - 1 :].startswith('"titel"')  # the key, not its value


@pytest.mark.parametrize(
    ("where", "key", "hint"),
    [
        ("/properties/on", "ReadOnly", "did you mean 'readOnly'?"),
        ("/properties/on", "obervable", "did you mean 'observable'?"),
        ("/properties/on/forms/0", "contenttype", "did you mean 'contentType'?"),
        ("/actions/toggle", "idempotant", "did you mean 'idempotent'?"),
        ("", "lastModified", "did you mean 'modified'?"),
    ],
)
def test_did_you_mean_at_each_position(where: str, key: str, hint: str) -> None:
    data = td()
    target = data
    for token in where.split("/")[1:]:
        target = target[int(token)] if isinstance(target, list) else target[token]
    target[key] = True
    [d] = terms(data)
    assert (d.code, d.pointer, d.hint) == ("TD201", f"{where}/{key}", hint)


def test_misplaced_term_is_named_as_such() -> None:
    data = td()
    data["actions"]["toggle"]["input"] = {"type": "integer", "observable": True}
    data["actions"]["toggle"]["type"] = "string"
    found = terms(data)
    assert [(d.code, d.pointer) for d in found] == [
        ("TD201", "/actions/toggle/input/observable"),
        ("TD201", "/actions/toggle/type"),
    ]
    assert "is a TD term, but not valid in a data schema" in found[0].message
    assert found[0].hint == "it is a term of: property affordances"
    assert found[1].hint == "data schema terms of an action belong in its 'input' or 'output' schema"


def test_json_schema_keywords_outside_td_are_explained() -> None:
    data = td()
    data["properties"]["on"]["additionalProperties"] = False
    [d] = terms(data)
    assert d.code == "TD201" and "JSON Schema keyword" in (d.hint or "")


def test_security_scheme_terms_depend_on_the_scheme() -> None:
    data = td(
        securityDefinitions={
            "b": {"scheme": "basic", "in": "header", "name": "Authorization", "qop": "auth"},
            "d": {"scheme": "digest", "qop": "auth"},
            "o": {"scheme": "oauth2", "flow": "code", "token": "https://e.com/t", "scopes": ["a"]},
        }
    )
    [d] = terms(data)
    assert (d.code, d.pointer) == ("TD201", "/securityDefinitions/b/qop")
    assert "basic security scheme" in d.message


def test_undeclared_prefix_reported_once_per_prefix() -> None:
    data = td(**{"ros:masterURI": "http://localhost:11311/"})
    data["properties"]["on"]["forms"][0].update({"ros:TopicName": "/state", "ros:Role": "Subscriber"})
    data["actions"]["toggle"]["forms"][0]["mqv:topic"] = "t"
    found = terms(data)
    assert [(d.code, d.pointer) for d in found] == [  # at the first use in document order
        ("TD202", "/properties/on/forms/0/ros:TopicName"),
        ("TD202", "/actions/toggle/forms/0/mqv:topic"),
    ]
    assert "'ros'" in found[0].message and "3 uses" in found[0].message
    assert "'mqv'" in found[1].message
    assert '"ros"' in (found[0].hint or "")


def test_declared_prefixes_are_accepted() -> None:
    context = [
        "https://www.w3.org/2022/wot/td/v1.1",
        {"ros": "https://example.com/ros#", "saref": "https://saref/"},
    ]
    data = td(**{"@context": context, "ros:masterURI": "http://localhost:11311/"})
    data["properties"]["on"]["forms"][0]["ros:TopicName"] = "/state"
    data["properties"]["on"]["saref:hasState"] = "x"
    data["properties"]["on"]["forms"][0]["htv:methodName"] = "GET"  # predefined by the TD context
    data["properties"]["on"]["https://example.com/vocab#term"] = 1  # an absolute IRI, not a compact one
    assert terms(data) == []


def test_rosv_binding_terms_via_declared_prefix_or_bundled_context() -> None:
    data = td()
    data["properties"]["on"]["forms"][0].update({"rosv:name": "/on", "rosv:type": "std_msgs/msg/Bool"})
    [d] = terms(data)
    assert d.code == "TD202" and "'rosv'" in d.message
    inline = td(**{"@context": ["https://www.w3.org/2022/wot/td/v1.1", {"rosv": "https://td2adaptor.dev/ns/rosv#"}]})
    inline["properties"] = data["properties"]
    assert terms(inline) == []
    bundled = td(**{"@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"]})
    bundled["properties"] = data["properties"]
    assert terms(bundled) == []


def test_unknown_remote_context_is_mentioned_in_the_hint() -> None:
    data = td(**{"@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://example.com/ctx"], "ex:x": 1})
    [d] = terms(data)
    assert d.code == "TD202" and "https://example.com/ctx" in (d.hint or "")


def test_user_chosen_names_are_not_terms() -> None:
    data = td(
        titles={"en": "Lamp", "de": "Lampe"},
        uriVariables={"titel": {"type": "string"}},
        schemaDefinitions={"readonly": {"type": "string"}},
        securityDefinitions={"my:sc": {"scheme": "nosec"}},
        security="my:sc",
    )
    data["properties"]["titel"] = {
        "type": "object",
        "properties": {"obervable": {"type": "string"}},
        "forms": [{"href": "x"}],
    }
    data["actions"]["foo bar"] = {
        "forms": [{"href": "x"}],
        "uriVariables": {"hrefx": {"type": "number"}},
        "input": {"type": "array", "items": {"type": "object", "properties": {"x": {"type": "number"}}}},
    }
    data["properties"]["on"]["const"] = {"titel": 1}  # data, not structure
    data["properties"]["on"]["default"] = {"anything": [{"goes": True}]}
    assert terms(data) == []


def test_trailing_colon_in_a_data_schema_member_name() -> None:
    data = td()
    data["properties"]["status"] = {
        "type": "object",
        "properties": {"battery": {"type": "object", "properties": {"level:": {"type": "number"}}}},
        "forms": [{"href": "x"}],
    }
    [d] = terms(data)
    assert (d.code, d.pointer) == ("TD203", "/properties/status/properties/battery/properties/level:")
    assert d.hint == "did you mean 'level'?"
    assert "suspicious property name" in d.message


def test_colon_member_name_with_declared_prefix_is_fine_and_other_colons_are_suspicious() -> None:
    context = ["https://www.w3.org/2022/wot/td/v1.1", {"ex": "https://example.com/#"}]
    data = td(**{"@context": context})
    data["properties"]["on"] = {
        "type": "object",
        "properties": {"ex:a": {"type": "number"}, "a:b": {"type": "number"}},
        "forms": [{"href": "x"}],
    }
    [d] = terms(data)
    assert (d.code, d.pointer) == ("TD203", "/properties/on/properties/a:b")
    assert "'a'" in (d.hint or "")


def test_nested_members_are_walked() -> None:
    data = td()
    data["properties"]["on"]["forms"][0]["response"] = {"contentType": "application/json", "contentTyp": "x"}
    data["properties"]["on"]["forms"][0]["additionalResponses"] = [{"success": False, "shema": "e"}]
    data["actions"]["toggle"]["output"] = {"oneOf": [{"type": "string", "maxlength": 3}]}
    data["links"] = [{"href": "https://e.com", "rell": "item"}]
    data["version"] = {"instance": "1", "firmware": "2"}
    found = [(d.pointer, d.hint) for d in terms(data)]
    assert found == [
        ("/properties/on/forms/0/response/contentTyp", "did you mean 'contentType'?"),
        ("/properties/on/forms/0/additionalResponses/0/shema", "did you mean 'schema'?"),
        ("/actions/toggle/output/oneOf/0/maxlength", "did you mean 'maxLength'?"),
        ("/links/0/rell", "did you mean 'rel'?"),
        (
            "/version/firmware",
            "TD 1.1 does not define it here, so consumers ignore it; for an extension use a compact IRI "
            "(prefix:term) with the prefix declared in @context",
        ),
    ]


def test_misplaced_affordance_and_schema_hints() -> None:
    data = td(lamp={"forms": [{"href": "x"}]})
    data["properties"]["on"] = {
        "type": "object",
        "properties": {"stamp": {"type": "object", "properties": {}, "frame_id": {"type": "string"}}},
        "forms": [{"href": "x"}],
    }
    found = terms(data)
    assert [d.pointer for d in found] == ["/properties/on/properties/stamp/frame_id", "/lamp"]
    hints = {d.pointer: d.hint or "" for d in found}
    assert "properties, actions or events" in hints["/lamp"]
    assert "inside 'properties'" in hints["/properties/on/properties/stamp/frame_id"]


def test_thing_model_terms() -> None:
    model = {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1"],
        "@type": "tm:ThingModel",
        "title": "Lamp {{N}}",
        "tm:optional": ["/properties/status"],
        "version": {"model": "1.0.0"},
        "links": [
            {
                "rel": "tm:submodel",
                "href": "./sub.tm.json",
                "type": "application/tm+json",
                "instanceName": "a",
            }
        ],
        "properties": {"status": {"tm:ref": "https://example.com/m.tm.jsonld#/properties/s", "unit": "%"}},
    }
    assert terms(model) == []


def test_comments_and_embedded_contexts_are_tolerated() -> None:
    data = td(**{"$comment": "example"})
    data["properties"]["on"]["@context"] = {"whatever": "https://e.com/"}
    assert terms(data) == []


def test_odd_shapes_do_not_crash() -> None:
    shapes: list[Any] = [
        [],
        "x",
        {"properties": [], "actions": {"a": "b"}, "forms": "x", "links": {"href": 1}},
        {"@context": 5, "securityDefinitions": {"s": "nosec"}, "properties": {"p": {"items": [1, {"x": 1}]}}},
    ]
    for data in shapes:
        terms(data)
    found = terms({"links": {"hreff": "x"}, "properties": {"p": {"properties": {"a:": 1}}}})
    assert [d.code for d in found] == ["TD201", "TD203"]


def _corpus_findings(files: list[wot_corpus.CorpusFile]) -> dict[str, set[tuple[str, str]]]:
    seen: dict[str, set[tuple[str, str]]] = {}
    for f in files:
        diags = Diagnostics()
        doc = load_path(str(f.path), diags)
        if doc is None:
            continue
        before = len(diags)
        check_terms(doc, diags)
        new = diags.items[before:]
        assert all(d.severity is Severity.WARNING for d in new), f.rel
        seen[f.rel] = {(d.code, d.pointer) for d in new}
    return seen


def test_playground_corpus_findings_are_warnings() -> None:
    corpus = wot_corpus.require_corpus()  # ../shared's, else the npm snapshot
    assert len(_corpus_findings(corpus.files())) == corpus.count()


def test_playground_corpus_findings() -> None:
    seen = _corpus_findings(wot_corpus.require_corpus().exact())  # names the files of ../shared's 98
    assert len(seen) == 98
    assert seen["valid/simple.json"] == set()
    assert seen["tm_valid/optional.json"] == set()
    assert seen["valid/MetadataThing.json"] == {("TD201", "/area51")}
    assert seen["valid/readWriteAllProperties.json"] == {("TD201", "/versioning")}
    assert seen["valid/versionThing.json"] == {("TD202", "/version/xyz:firmware")}
    assert {code for code, _ in seen["valid/mqtt-experimental.json"]} == {"TD201", "TD202"}


def test_a_misspelt_binding_term_is_named_with_the_term_meant() -> None:
    from td2adaptor.frontend.jsonsrc import parse_json
    from td2adaptor.frontend.terms import binding_terms, check_terms

    td = {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "title": "T",
        "properties": {"p": {"forms": [{"href": "ros:///p", "rosv:nmae": "/p", "rosv:type": "std_msgs/msg/Bool"}]}},
    }
    diags = Diagnostics()
    doc = parse_json(json.dumps(td).encode(), "t.json", diags)
    assert doc is not None
    check_terms(doc, diags)
    [d] = [d for d in diags if d.code == "TD201"]
    assert d.message == "unknown binding term 'rosv:nmae' in a form" and d.hint == "did you mean 'rosv:name'?"
    assert d.pointer == "/properties/p/forms/0/rosv:nmae"
    assert {"rosv:name", "rosv:type", "rosv:procedure", "rosv:masterURI"} <= binding_terms()
