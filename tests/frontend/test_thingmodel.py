"""Thing Model → TD instantiation: placeholders, tm:extends, tm:ref, tm:optional, the TD it yields, checking a
TD against its model, and the Playground's Thing Model corpus."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import jsonschema
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.frontend.jsonsrc import JsonDocument, load_path, parse_json
from td2adaptor.frontend.thingmodel import (
    CODES,
    check_against_model,
    instantiate,
    is_thing_model,
    load_placeholder_map,
    merge_patch,
    parse_set_options,
)
from tests import wot_corpus

DATA = Path(__file__).parents[1] / "data" / "tm"
RB1_VALUES = {"SERIAL": "0042", "MAX_SPEED": 1.5}
PLACEHOLDER_VALUES: dict[str, Any] = {
    "SERIAL": 7,
    "MODEL": "RB-1",
    "N": 3,
    "MAX": 47.7,
    "RO": True,
    "SENSOR": "sonar",
    "ARR": [1, 2, 3],
}


def load(rel: str | Path) -> JsonDocument:
    diags = Diagnostics()
    doc = load_path(str(DATA / rel if isinstance(rel, str) else rel), diags)
    assert doc is not None and not diags.has_errors, list(diags)
    return doc


def run(rel: str | Path, values: dict[str, Any] | None = None, **kw: Any) -> tuple[dict[str, Any] | None, Diagnostics]:
    diags = Diagnostics()
    td = instantiate(load(rel), values or {}, diags, **kw)
    return td, diags


def from_text(data: Any, name: str = "mem.tm.json") -> JsonDocument:
    diags = Diagnostics()
    doc = parse_json(json.dumps(data), name, diags)
    assert doc is not None
    return doc


def tm(**members: Any) -> dict[str, Any]:
    """A minimal model with the given members."""
    return {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1"],
        "@type": "tm:ThingModel",
        "title": "T",
        **members,
    }


def of(diags: Diagnostics, code: str) -> list[Any]:
    return [d for d in diags if d.code == code]


# ---------------------------------------------------------------------------------------------------------
# basics


def test_codes_are_in_the_tm3xx_range_and_described() -> None:
    assert CODES and all(re.fullmatch(r"TM3\d\d", c) and text for c, text in CODES.items())


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"@type": "tm:ThingModel"}, True),
        ({"@type": ["saref:Device", "tm:ThingModel"]}, True),
        ({"@type": "https://www.w3.org/2019/wot/tm#ThingModel"}, True),
        ({"@type": "Thing"}, False),
        ({"title": "no type"}, False),
        (["tm:ThingModel"], False),
        ("tm:ThingModel", False),
    ],
)
def test_is_thing_model(data: object, expected: bool) -> None:
    assert is_thing_model(data) is expected


def test_merge_patch_follows_rfc7396() -> None:
    target = {"a": {"b": 1, "c": [1, 2]}, "d": 1}
    patch = {"a": {"b": None, "c": [3], "e": {"f": None, "g": 1}}, "d": None, "h": "x"}
    assert merge_patch(target, patch) == {"a": {"c": [3], "e": {"g": 1}}, "h": "x"}
    assert target == {"a": {"b": 1, "c": [1, 2]}, "d": 1}  # untouched
    assert merge_patch({"a": 1}, [1]) == [1]
    assert merge_patch(5, {"a": 1}) == {"a": 1}


# ---------------------------------------------------------------------------------------------------------
# placeholder values


def test_set_options_parse_json_values_else_keep_text() -> None:
    diags = Diagnostics()
    values = parse_set_options(
        [
            "MAX=47.7",
            "N=3",
            "ON=true",
            "ARR=[1,2]",
            'OBJ={"a":1}',
            "NAME=rb1_base_a",
            "EXPR=a=b",
            "EMPTY=",
            'QUOTED="007"',
            "NAN=NaN",
            "HUGE=1e999",
            "{{BRACED}}=x",
            " SPACED =1",
        ],
        diags,
    )
    assert values == {
        "MAX": 47.7,
        "N": 3,
        "ON": True,
        "ARR": [1, 2],
        "OBJ": {"a": 1},
        "NAME": "rb1_base_a",
        "EXPR": "a=b",
        "EMPTY": "",
        "QUOTED": "007",
        "NAN": "NaN",
        "HUGE": "1e999",
        "BRACED": "x",
        "SPACED": 1,
    }
    assert isinstance(values["MAX"], float) and values["ON"] is True
    assert not list(diags)


def test_set_options_report_bad_items_and_repeats() -> None:
    diags = Diagnostics()
    values = parse_set_options(["novalue", "=5", "A=1", "A=2"], diags)
    assert values == {"A": 2}
    assert [d.code for d in diags.errors()] == ["TM305", "TM305"]
    assert "'novalue'" in diags.errors()[0].message and "NAME=VALUE" in diags.errors()[0].message
    assert [d.code for d in diags.warnings()] == ["TM306"]


def test_placeholder_map_from_yaml_keeps_dates_as_text() -> None:
    diags = Diagnostics()
    values = load_placeholder_map(DATA / "values" / "rb1.yaml", diags)
    assert values == {
        "SERIAL": "0042",
        "MAX_SPEED": 1.5,
        "commissioned": "2024-05-01",
        "tags": ["indoor", "lab"],
    }
    assert not list(diags)


def test_placeholder_map_from_json() -> None:
    diags = Diagnostics()
    assert load_placeholder_map(DATA / "values" / "rb1.json", diags) == RB1_VALUES
    assert not list(diags)


@pytest.mark.parametrize(
    ("name", "text", "code", "words", "line"),
    [
        ("m.yml", "A: [1, 2\nB: 3\n", "TM307", "invalid YAML", 2),
        ("m.yaml", "A: 1\nA: 2\n", "TM307", "duplicate key 'A'", 2),
        ("m.yaml", "- 1\n- 2\n", "TM308", "is a list", None),
        ("m.yaml", "", "TM308", "is empty", None),
        ("m.yaml", "1: x\n", "TM308", "not a string", None),
        ("m.yaml", "A: .nan\n", "TM308", "not a JSON number", None),
        ("m.yaml", "A: !!binary aGVsbG8=\n", "TM308", "bytes", None),
        ("m.yaml", "A: !!float abc\n", "TM307", "could not convert", None),
        ("m.yaml", "A: !!python/object:os.system x\n", "TM307", "could not determine a constructor", 1),
        ("m.yaml", "A: &a [*a]\n", "TM308", "contains itself", None),
        ("m.json", "[1, 2]", "TM308", "is a list", None),
        ("m.json", '{"A": 1, "A": 2}', "TD003", "duplicate key", 1),
        ("m.json", '{"A": ', "TD004", "invalid JSON", 1),
        ("m.toml", "A = 1", "TM307", "extension .toml", None),
    ],
)
def test_placeholder_map_problems_are_diagnostics(
    tmp_path: Path, name: str, text: str, code: str, words: str, line: int | None
) -> None:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    diags = Diagnostics()
    assert load_placeholder_map(path, diags) is None
    errors = diags.errors()
    assert errors and errors[0].code == code and words in errors[0].message, errors
    assert errors[0].line == line
    assert errors[0].file is not None and errors[0].file.endswith(name)


def test_placeholder_map_missing_file(tmp_path: Path) -> None:
    for name in ("gone.yaml", "gone.json"):
        diags = Diagnostics()
        assert load_placeholder_map(tmp_path / name, diags) is None
        assert diags.has_errors and name in diags.errors()[0].message


# ---------------------------------------------------------------------------------------------------------
# placeholders


def test_typed_and_in_string_placeholders_and_keys() -> None:
    td, diags = run("placeholders.tm.json", PLACEHOLDER_VALUES)
    assert td is not None, list(diags)
    speed = td["properties"]["speed"]
    assert speed["maximum"] == 47.7 and isinstance(speed["maximum"], float)
    assert speed["readOnly"] is True
    assert speed["description"] == "at most 47.7 m/s, read-only: true"
    assert "{{SENSOR}}_range" not in td["properties"]
    sonar = td["properties"]["sonar_range"]
    assert sonar["default"] == [1, 2, 3]
    assert sonar["description"] == "data: [1,2,3]"
    assert sonar["forms"][0]["href"] == "ros://robot/sonar"
    assert td["id"] == "urn:dev:robot:7"
    assert td["title"] == "Base RB-1 No. 3"


def test_runtime_placeholder_robot_name_is_kept_with_one_info() -> None:
    td, diags = run("placeholders.tm.json", PLACEHOLDER_VALUES)
    assert td is not None
    assert td["properties"]["speed"]["forms"][0]["rosv:name"] == "/{{robotName}}/speed"
    assert td["properties"]["sonar_range"]["forms"][0]["rosv:name"] == "/{{robotName}}/sonar/range"
    kept = of(diags, "TM302")
    assert len(kept) == 1 and kept[0].severity is Severity.INFO and "{{robotName}}" in kept[0].message
    assert kept[0].pointer == "/properties/speed/forms/0/rosv:name"


def test_runtime_placeholder_is_substituted_when_given() -> None:
    td, diags = run("placeholders.tm.json", PLACEHOLDER_VALUES | {"robotName": "rb1_base_a"})
    assert td is not None
    assert td["properties"]["speed"]["forms"][0]["rosv:name"] == "/rb1_base_a/speed"
    assert not of(diags, "TM302")


def test_all_missing_placeholders_in_one_error() -> None:
    td, diags = run("placeholders.tm.json", {"MODEL": "RB-1", "ARR": [1]})
    assert td is None
    errors = diags.errors()
    assert [d.code for d in errors] == ["TM301"]
    message = errors[0].message
    for name in ("SERIAL", "N", "MAX", "RO", "SENSOR"):
        assert re.search(rf"\b{name} \(at /", message), message
    assert "robotName" not in message and "MODEL" not in message
    assert "MAX (at /properties/speed/maximum, /properties/speed/d" in message  # every place it is used
    assert "SENSOR (at /properties/{{SENSOR}}_range, /properties/{{SENSOR}}_range/forms/0/href" in message
    assert errors[0].pointer == "/id"  # where the first missing one is first used


def test_keep_nothing_makes_robot_name_required() -> None:
    td, diags = run("placeholders.tm.json", PLACEHOLDER_VALUES, keep=())
    assert td is None
    assert [d.code for d in diags.errors()] == ["TM301"]
    assert (
        "robotName (at /properties/speed/forms/0/rosv:name, /properties/{{SENSOR}}_range/forms/0/rosv:name)"
        in diags.errors()[0].message
    )


def test_unused_values_are_mentioned() -> None:
    td, diags = run("placeholders.tm.json", PLACEHOLDER_VALUES | {"MAX_SPED": 2})
    assert td is not None
    assert [d.message for d in of(diags, "TM303")] == ["values given but not used by the model: MAX_SPED"]


def test_placeholder_names_may_have_spaces_and_values_are_not_resubstituted() -> None:
    doc = from_text(
        tm(description="{{ A }} and {{B}}", properties={"p": {"const": "{{ A }}", "forms": [{"href": "x"}]}})
    )
    diags = Diagnostics()
    td = instantiate(doc, {"A": "{{B}}", "B": None}, diags)
    assert td is not None, list(diags)
    assert td["description"] == "{{B}} and null"
    assert td["properties"]["p"]["const"] == "{{B}}"


def test_keys_that_collide_after_substitution() -> None:
    doc = from_text(tm(properties={"{{A}}_x": {"type": "string"}, "a_x": {"type": "number"}}))
    diags = Diagnostics()
    assert instantiate(doc, {"A": "a"}, diags) is None
    assert [(d.code, d.pointer) for d in diags.errors()] == [("TM304", "/properties/a_x")]


# ---------------------------------------------------------------------------------------------------------
# tm:extends


def test_extends_chain_across_folders() -> None:
    td, diags = run("robot/rb1_base.tm.json", RB1_VALUES)
    assert td is not None, list(diags)
    status = td["properties"]["status"]
    # inherited from common/base/thing.tm.json (two levels up), patched by the child
    assert status["enum"] == ["ok", "error", "charging"]  # arrays replace
    assert status["description"] == "state of the base" and status["readOnly"] is True
    assert status["forms"][0]["rosv:name"] == "/{{robotName}}/status"
    # from common/mobile_base.tm.json
    assert td["properties"]["odom"]["forms"][0]["rosv:name"] == "/{{robotName}}/odom"
    linear = td["actions"]["move"]["input"]["properties"]
    assert linear == {
        "linear": {"type": "number", "maximum": 1.5},
        "angular": {"type": "number", "maximum": 2.0},
    }
    # tm:ref in the parent resolved relative to the parent's folder
    battery = td["properties"]["battery"]
    assert battery["minimum"] == 0 and battery["maximum"] == 100 and battery["unit"] == "%"
    assert battery["title"] == "Battery level"
    # top-level: the child's title and id, the root's description, context union
    assert td["title"] == "RB-1 base 0042" and td["id"] == "urn:dev:robotnik:rb1:0042"
    assert td["description"] == "What every robot offers"
    assert td["@context"] == [
        "https://www.w3.org/2022/wot/td/v1.1",
        {"rosv": "https://td2adaptor.dev/ns/rosv#"},
    ]
    assert td["security"] == ["nosec_sc"] and not of(diags, "TM341")
    assert td["links"] == [
        {"rel": "manual", "href": "https://example.com/rb1/manual.pdf"},
        {"rel": "type", "href": "rb1_base.tm.json", "type": "application/tm+json"},
    ]
    assert not diags.warnings()


def test_extends_several_parents_later_wins_and_null_deletes() -> None:
    td, diags = run("diamond/top.tm.json")
    assert td is not None, list(diags)
    assert td["description"] == "from right"
    # left's and right's patches of base's "side", applied in link order
    assert td["properties"] == {
        "side": {"type": "string", "description": "which side", "const": "right", "readOnly": True}
    }
    # base.tm.json (reached twice) is resolved once: its warning is not repeated
    not_tm = of(diags, "TM314")
    assert len(not_tm) == 1 and not_tm[0].file == "base.tm.json" and not_tm[0].line == 5


def test_extends_cycle_is_one_error_naming_the_cycle() -> None:
    td, diags = run("cycles/a.tm.json")
    assert td is None
    errors = diags.errors()
    assert [d.code for d in errors] == ["TM312"]
    assert errors[0].message == "tm:extends cycle: a.tm.json → b.tm.json → a.tm.json"
    assert (errors[0].file, errors[0].line, errors[0].pointer) == ("b.tm.json", 5, "/links/0/href")


def test_extends_itself() -> None:
    td, diags = run("cycles/self.tm.json")
    assert td is None
    assert [d.message for d in diags.errors()] == ["tm:extends cycle: self.tm.json → self.tm.json"]


def test_missing_parent_is_not_found_and_other_problems_still_reported() -> None:
    td, diags = run("missing/missing_parent.tm.json")
    assert td is None
    assert [d.code for d in diags.errors()] == ["TM310", "TM301"]
    missing = diags.errors()[0]
    assert missing.message == "extended Thing Model ../nowhere/parent.tm.json not found"
    assert missing.pointer == "/links/0/href" and missing.file is None  # in the root: the caller locates it


def test_problem_in_a_parent_is_located_in_the_parent() -> None:
    td, diags = run("missing/child.tm.json")
    assert td is None
    (error,) = diags.errors()
    assert error.code == "TM321" and error.file == "parent_badref.tm.json" and error.line == 6


def test_remote_parent_is_never_fetched() -> None:
    td, diags = run("missing/remote_parent.tm.json")
    assert td is None
    (error,) = diags.errors()
    assert error.code == "TM311" and error.pointer == "/links/0/href"
    assert "https://example.com/models/base.tm.jsonld" in error.message and "not fetched" in error.message


def test_extends_link_without_href() -> None:
    doc = from_text(tm(links=[{"rel": "tm:extends"}, {"rel": "tm:extends", "href": "urn:x:y"}]))
    diags = Diagnostics()
    assert instantiate(doc, {}, diags) is None
    assert [(d.code, d.pointer) for d in diags.errors()] == [
        ("TM313", "/links/0"),
        ("TM313", "/links/1/href"),
    ]


# ---------------------------------------------------------------------------------------------------------
# tm:ref


def test_ref_imports_and_merge_patches() -> None:
    td, diags = run("refs/model.tm.json")
    assert td is not None, list(diags)
    # lib.tm.json#/properties/battery, itself a tm:ref to #/schemaDefinitions/percent of lib.tm.json
    assert td["properties"]["charge"] == {
        "type": "number",
        "minimum": 0,
        "maximum": 100,
        "unit": "%",
        "title": "Charge",
        "readOnly": True,
        "enum": [10, 20],  # array replaced
    }  # "observable": null deleted the imported true
    charge2 = td["properties"]["charge2"]
    assert "unit" not in charge2 and charge2["title"] == "Charge" and charge2["enum"] == [10, 20]
    assert td["actions"]["dock"]["input"] == {"type": "number", "minimum": 0, "maximum": 50, "unit": "%"}
    assert "tm:ref" not in json.dumps(td)


def test_broken_refs_each_reported() -> None:
    td, diags = run("refs/broken.tm.json")
    assert td is None
    assert [(d.code, d.pointer) for d in diags.errors()] == [
        ("TM321", "/properties/a/tm:ref"),
        ("TM310", "/properties/b/tm:ref"),
        ("TM320", "/properties/c/tm:ref"),
        ("TM311", "/properties/d/tm:ref"),
    ]
    assert "nowhere.tm.json not found" in diags.errors()[1].message
    assert "not fetched" in diags.errors()[3].message


def test_ref_cycle_in_one_file_is_one_error() -> None:
    td, diags = run("cycles/ref_cycle.tm.json")
    assert td is None
    (error,) = diags.errors()
    assert error.code == "TM322"
    assert error.message == (
        "tm:ref cycle: ref_cycle.tm.json#/properties/b → ref_cycle.tm.json#/properties/a"
        " → ref_cycle.tm.json#/properties/b"
    )


def test_ref_cycle_across_files() -> None:
    td, diags = run("cycles/ref_x.tm.json")
    assert td is None
    (error,) = diags.errors()
    assert error.code == "TM322" and "ref_x.tm.json#/properties/p" in error.message
    assert "ref_y.tm.json#/properties/q" in error.message


def test_ref_into_its_own_subtree_is_a_cycle() -> None:
    doc = from_text(tm(properties={"a": {"type": "array", "items": {"tm:ref": "#/properties/a"}}}))
    diags = Diagnostics()
    assert instantiate(doc, {}, diags) is None
    assert [d.code for d in diags.errors()] == ["TM322"]


def test_bare_ref_imports_any_value() -> None:
    model = tm(
        schemaDefinitions={"states": ["on", "off"]},
        properties={
            "p": {
                "type": "string",
                "enum": {"tm:ref": "#/schemaDefinitions/states"},
                "forms": [{"href": "x"}],
            }
        },
    )
    td = instantiate(from_text(model), {}, Diagnostics())
    assert td is not None and td["properties"]["p"]["enum"] == ["on", "off"]


def test_refs_that_multiply_are_bounded() -> None:
    defs = {
        f"d{i}": {
            "a": {"tm:ref": f"#/schemaDefinitions/d{i + 1}"},
            "b": {"tm:ref": f"#/schemaDefinitions/d{i + 1}"},
        }
        for i in range(30)
    }
    defs["d30"] = {"type": "string"}
    model = tm(schemaDefinitions=defs, properties={"p": {"tm:ref": "#/schemaDefinitions/d0"}})
    diags = Diagnostics()
    assert instantiate(from_text(model), {}, diags) is None
    assert [d.code for d in diags.errors()] == ["TM323"]


# ---------------------------------------------------------------------------------------------------------
# tm:optional


def test_optional_all_kept_by_default() -> None:
    td, diags = run("optional/lamp.tm.json", {"BATTERY_MAX": 100})
    assert td is not None
    assert set(td["properties"]) == {"status", "battery"} and set(td["actions"]) == {"toggle", "dock"}
    assert "tm:optional" not in td and not of(diags, "TM333")


def test_optional_none_needs_no_values_for_them() -> None:
    td, diags = run("optional/lamp.tm.json", include_optional=False)
    assert td is not None, list(diags)
    assert set(td["properties"]) == {"status"} and set(td["actions"]) == {"toggle"}
    assert set(td["events"]) == {"overheating"}
    assert "tm:optional" not in td
    (info,) = of(diags, "TM333")
    assert info.message == "optional affordances left out: /properties/battery, /actions/dock"


@pytest.mark.parametrize(
    ("selection", "properties", "actions"),
    [
        (["battery"], {"status", "battery"}, {"toggle"}),
        (["/actions/dock"], {"status"}, {"toggle", "dock"}),
        ("dock", {"status"}, {"toggle", "dock"}),
        (["#/properties/battery", "dock"], {"status", "battery"}, {"toggle", "dock"}),
        ([], {"status"}, {"toggle"}),
    ],
)
def test_optional_selection(selection: Any, properties: set[str], actions: set[str]) -> None:
    td, diags = run("optional/lamp.tm.json", {"BATTERY_MAX": 100}, include_optional=selection)
    assert td is not None, list(diags)
    assert set(td["properties"]) == properties and set(td["actions"]) == actions


def test_optional_selection_of_a_mandatory_or_unknown_affordance() -> None:
    td, diags = run("optional/lamp.tm.json", include_optional=["status", "/properties/nope"])
    assert td is None
    assert [d.code for d in diags.errors()] == ["TM332", "TM332"]
    assert "/properties/battery, /actions/dock" in diags.errors()[0].message


def test_optional_pointers_must_name_whole_affordances() -> None:
    td, diags = run("optional/bad.tm.json")
    assert td is None
    assert [(d.code, d.pointer) for d in diags.errors()] == [
        ("TM331", "/tm:optional/0"),
        ("TM331", "/tm:optional/1"),
        ("TM330", "/tm:optional/2"),
    ]
    assert "'#/properties/status/type'" in diags.errors()[1].message


def test_optional_not_a_list() -> None:
    doc = from_text(tm(**{"tm:optional": "/properties/a"}, properties={"a": {}}))
    diags = Diagnostics()
    assert instantiate(doc, {}, diags) is None
    assert [(d.code, d.pointer) for d in diags.errors()] == [("TM330", "/tm:optional")]


# ---------------------------------------------------------------------------------------------------------
# the TD it yields


def test_td_type_and_links() -> None:
    doc = from_text(
        tm(
            **{"@type": ["tm:ThingModel", "saref:Device"]},
            links=[
                {"rel": "type", "href": "old.tm.json"},
                {"rel": "tm:submodel", "href": "arm.tm.json", "instanceName": "arm"},
            ],
        )
    )
    diags = Diagnostics()
    td = instantiate(doc, {}, diags, model_href="models/rb1.tm.json")
    assert td is not None
    assert td["@type"] == ["Thing", "saref:Device"]
    assert td["links"] == [
        {"rel": "tm:submodel", "href": "arm.tm.json", "instanceName": "arm"},
        {"rel": "type", "href": "models/rb1.tm.json", "type": "application/tm+json"},
    ]
    assert [d.code for d in diags.warnings()] == ["TM347"]


def test_model_read_from_stdin_gets_no_type_link() -> None:
    diags = Diagnostics()
    td = instantiate(from_text(tm()), {}, diags)
    assert td is not None and "links" not in td
    assert of(diags, "TM349")


def test_type_link_href_is_relative_by_default() -> None:
    td, _ = run(DATA.resolve() / "robot" / "rb1_base.tm.json", RB1_VALUES)
    assert td is not None
    assert td["links"][-1]["href"] == "rb1_base.tm.json"


@pytest.mark.parametrize(
    ("context", "expected", "adjusted"),
    [
        ("https://www.w3.org/2022/wot/td/v1.1", "https://www.w3.org/2022/wot/td/v1.1", False),
        (
            [
                "https://www.w3.org/2019/wot/td/v1",
                "https://www.w3.org/2022/wot/td/v1.1",
                {"ex": "https://ex.org#"},
            ],
            [
                "https://www.w3.org/2019/wot/td/v1",
                "https://www.w3.org/2022/wot/td/v1.1",
                {"ex": "https://ex.org#"},
            ],
            False,
        ),
        (
            [{"ex": "https://ex.org#"}, "https://www.w3.org/2022/wot/td/v1.1"],
            ["https://www.w3.org/2022/wot/td/v1.1", {"ex": "https://ex.org#"}],
            True,
        ),
        (
            ["https://www.w3.org/2022/wot/td/v1.1", "https://www.w3.org/2019/wot/td/v1"],
            ["https://www.w3.org/2019/wot/td/v1", "https://www.w3.org/2022/wot/td/v1.1"],
            True,
        ),
        (
            ["https://www.w3.org/2022/wot/tm", {"ex": "https://ex.org#"}],
            ["https://www.w3.org/2022/wot/td/v1.1", {"ex": "https://ex.org#"}],
            True,
        ),
        (None, ["https://www.w3.org/2022/wot/td/v1.1"], True),
    ],
)
def test_td_context(context: Any, expected: Any, adjusted: bool) -> None:
    model = tm(**{"@context": context})
    if context is None:
        del model["@context"]
    diags = Diagnostics()
    td = instantiate(from_text(model), {}, diags)
    assert td is not None
    assert td["@context"] == expected
    assert bool(of(diags, "TM340")) is adjusted


def test_tm_terms_are_dropped() -> None:
    doc = from_text(tm(**{"tm:foo": 1}, properties={"p": {"tm:bar": 2, "forms": [{"href": "x"}]}}))
    diags = Diagnostics()
    td = instantiate(doc, {}, diags)
    assert td is not None
    assert "tm:" not in json.dumps(td).replace("application/tm+json", "")
    assert [d.message for d in of(diags, "TM348")] == [
        "Thing Model terms dropped from the TD: tm:foo, properties/p/tm:bar"
    ]


def test_security_nosec_added_when_the_model_has_none() -> None:
    td, diags = run("refs/model.tm.json")
    assert td is not None
    assert td["securityDefinitions"] == {"nosec_sc": {"scheme": "nosec"}} and td["security"] == "nosec_sc"
    assert [d.severity for d in of(diags, "TM341")] == [Severity.INFO]


def test_partial_security_is_a_warning_not_invented() -> None:
    diags = Diagnostics()
    td = instantiate(from_text(tm(security="basic_sc")), {}, diags)
    assert td is not None and "securityDefinitions" not in td
    assert [d.code for d in diags.warnings()] == ["TM342"]


def test_affordances_without_forms_are_warned_one_by_one() -> None:
    td, diags = run("refs/model.tm.json")
    assert td is not None
    assert [d.pointer for d in of(diags, "TM343")] == [
        "/properties/charge",
        "/properties/charge2",
        "/actions/dock",
    ]
    assert all(d.severity is Severity.WARNING for d in of(diags, "TM343"))
    assert "forms" not in td["properties"]["charge"]


def test_versions_and_title() -> None:
    diags = Diagnostics()
    td = instantiate(from_text(tm(version={"model": "2.1.0"})), {}, diags)
    assert td is not None and td["version"] == {"model": "2.1.0", "instance": "2.1.0"}
    assert of(diags, "TM345")
    model = tm(version="{{V}}")
    del model["title"]
    diags = Diagnostics()
    td = instantiate(from_text(model), {"V": "1.0"}, diags)
    assert td is not None
    assert [d.code for d in diags.warnings()] == ["TM346", "TM344"]


def test_not_a_thing_model() -> None:
    diags = Diagnostics()
    doc = load_path(str(wot_corpus.require_corpus().file("tm_invalid/absent_tm.json")), diags)
    assert doc is not None
    assert instantiate(doc, {}, diags) is None
    assert [d.code for d in diags.errors()] == ["TM300"]


def test_deep_nesting_is_a_diagnostic_not_a_crash() -> None:
    deep: Any = "leaf"
    for _ in range(5000):
        deep = {"a": deep}
    doc = JsonDocument("deep.tm.json", "", tm(properties={"p": deep}))
    diags = Diagnostics()
    assert instantiate(doc, {}, diags) is None
    assert [d.code for d in diags.errors()] == ["TM309"]


def test_the_robot_td_validates_against_the_official_schema() -> None:
    """Oracle only: the official TD 1.1 schema, read from the reference material, not shipped."""
    td, _ = run("robot/rb1_base.tm.json", RB1_VALUES)
    schema = wot_corpus.official_json("td-schema-v1.1.json")
    validator = jsonschema.Draft7Validator(schema, format_checker=jsonschema.Draft7Validator.FORMAT_CHECKER)
    assert [e.message for e in validator.iter_errors(td)] == []


def test_the_robot_td_passes_check_td() -> None:
    from td2adaptor.frontend.conformance import check_td  # written in parallel; present once integrated

    td, _ = run("robot/rb1_base.tm.json", RB1_VALUES)
    diags = Diagnostics()
    doc = parse_json(json.dumps(td, indent=2), "rb1_base.td.json", diags)
    assert doc is not None
    check_td(doc, diags)
    assert not diags.has_errors, [d.message for d in diags.errors()]


# ---------------------------------------------------------------------------------------------------------
# a TD against the model it links


def check(rel: str | Path) -> Diagnostics:
    diags = Diagnostics()
    check_against_model(load(rel), diags)
    return diags


def test_td_conforming_to_its_local_model() -> None:
    assert not list(check("td/good.td.json"))


def test_td_missing_a_mandatory_affordance_and_contradicting_a_type() -> None:
    diags = check("td/bad.td.json")
    assert [(d.code, d.pointer) for d in diags.errors()] == [
        ("TM353", "/properties/status/type"),
        ("TM352", ""),
    ]
    assert "actions/toggle" in diags.errors()[1].message  # battery and dock are optional: not reported


def test_td_against_a_model_with_parents() -> None:
    diags = check("td/robot.td.json")
    assert [(d.code, d.pointer) for d in diags] == [("TM352", "/properties")]
    assert "properties/odom" in diags.errors()[0].message


def test_td_linking_a_missing_local_model() -> None:
    diags = check("td/missing_model.td.json")
    assert [(d.code, d.pointer) for d in diags] == [("TM310", "/links/0/href")]
    assert "gone.tm.json not found" in diags.errors()[0].message


@pytest.mark.parametrize(
    "rel", ["invalid/usingTM.json", "warn/unavailableDirectTm.json", "warn/unavailableRecursiveTm.json"]
)
def test_td_linking_a_remote_model_is_one_warning(rel: str) -> None:
    # any version of the file: the npm snapshot's link to an older URL of the same model will do
    path = wot_corpus.require_corpus().file(rel, any_version=True)
    href = json.loads(path.read_text(encoding="utf-8"))["links"][0]["href"]
    diags = check(path)
    assert [(d.code, d.severity, d.message) for d in diags] == [
        (
            "TM350",
            Severity.WARNING,
            f"linked Thing Model {href} not fetched (offline); conformance to it not checked",
        )
    ]


def test_placeholder_affordance_names_match_any_instance(tmp_path: Path) -> None:
    (tmp_path / "m.tm.json").write_text(json.dumps(tm(properties={"{{S}}_range": {"type": "number"}})))
    td = {
        "title": "t",
        "links": [{"rel": "type", "href": "m.tm.json"}],
        "properties": {"sonar_range": {"type": "integer"}},
    }
    (tmp_path / "t.td.json").write_text(json.dumps(td))
    assert not list(check(tmp_path / "t.td.json"))
    td["properties"] = {"other": {}}
    (tmp_path / "t.td.json").write_text(json.dumps(td))
    assert [d.code for d in check(tmp_path / "t.td.json")] == ["TM352"]


def test_td_without_a_model_link_is_not_checked() -> None:
    for data in ({"title": "x"}, {"links": "nope"}, [1], {"links": [{"rel": "type"}, 5]}):
        diags = Diagnostics()
        check_against_model(from_text(data, "t.td.json"), diags)
        assert not list(diags)


# ---------------------------------------------------------------------------------------------------------
# the Playground's Thing Models


PLAYGROUND_VALUES: dict[str, Any] = {
    "THERMOSTATE_NUMBER": 4,
    "MQTT_BROKER_ADDRESS": "192.168.178.72:1883",
    "THERMOSTATE_TEMPERATURE_MAXIMUM": 47.7,
    "THERMOSTATE_TEMPERATURE_OBSERVABLE": True,
    "VERSION_INFO": {"instance": "xyz", "model": "ABC"},
    "PLACEHOLDER": "basic",
}
# these models extend or import remote models, which are never fetched: TM311 is their expected outcome
REMOTE = {
    "extend.json": "https://raw.githubusercontent.com/eclipse-thingweb/playground/master/packages/core/examples/tms/valid/version.json",
    "links.json": "http://example.com/SmartControlLampTM",
    "ref.json": "http://example.com/BasicOnOffTM.tm.jsonld#/properties/onOff",
    "overwrite.json": "http://example.com/SmartLampControlwithDimming.tm.jsonld#/properties/dim",
}


def playground(folder: str, *, exact: bool) -> list[Path]:
    """The corpus folder's files; `exact` when the test's expectations name its exact contents."""
    corpus = wot_corpus.require_corpus()
    files = [f.path for f in (corpus.exact(folder) if exact else corpus.files(folder))]
    assert files
    return files


def placeholder_names(path: Path) -> set[str]:
    return {m.strip() for m in re.findall(r"\{\{([ -z|~]+)\}\}", path.read_text(encoding="utf-8"))}


def test_playground_tm_valid_instantiate() -> None:
    files = playground("tm_valid", exact=True)  # REMOTE names the URLs
    assert len(files) == 13
    for path in files:
        names = placeholder_names(path)
        values = {n: PLAYGROUND_VALUES.get(n, "x") for n in names}
        diags = Diagnostics()
        doc = load_path(str(path), diags)
        assert doc is not None
        td = instantiate(doc, values, diags)
        errors = diags.errors()
        if path.name in REMOTE:
            assert td is None, path.name
            assert [d.code for d in errors] == ["TM311"], (path.name, errors)
            assert REMOTE[path.name].split("#")[0] in errors[0].message
            continue
        assert td is not None and not errors, (path.name, errors)
        text = json.dumps(td)
        assert "{{" not in text, path.name
        assert td["@type"] == "Thing" and "tm:optional" not in td
        assert td["links"][-1] == {"rel": "type", "href": path.name, "type": "application/tm+json"}
        if path.name == "placeholder.json":
            temperature = td["properties"]["temperature"]
            assert temperature["maximum"] == 47.7 and temperature["observable"] is True
            assert td["title"] == "Thermostate No. 4" and td["base"] == "mqtt://192.168.178.72:1883"
            assert td["version"] == {"instance": "xyz", "model": "ABC"}
    # every file with placeholders was given values for all of them, and the corpus does use placeholders
    assert any(placeholder_names(p) for p in files)


def test_playground_tm_invalid() -> None:
    outcome: dict[str, list[str]] = {}
    for path in playground("tm_invalid", exact=True):
        diags = Diagnostics()
        doc = load_path(str(path), diags)
        assert doc is not None
        td = instantiate(doc, {n: "x" for n in placeholder_names(path)}, diags)
        outcome[path.name] = [d.code for d in diags.errors()]
        assert (td is None) == bool(outcome[path.name])
    # what instantiation itself rejects; the rest are TM-schema violations (check_tm's job, tested below)
    assert outcome == {
        "absent_context.json": [],
        "absent_tm.json": ["TM300"],
        "no_curly_bracket.json": [],
        "optionalWrongLocation.json": ["TM331"],
        "single_curly_bracket.json": [],
        "unavailableParent.json": ["TM311"],
    }


def test_playground_unavailable_parent_cannot_be_resolved() -> None:
    td, diags = run(wot_corpus.require_corpus().file("tm_invalid/unavailableParent.json"))
    assert td is None
    (error,) = diags.errors()
    assert error.code == "TM311" and error.pointer == "/links/0/href"
    assert error.message.startswith(
        "extended Thing Model https://example.com/models/colored-lamp-1.0.0.tm.jsonld cannot be resolved"
    )


def test_playground_schema_and_resolution_together_reject_every_tm_invalid() -> None:
    from td2adaptor.frontend.conformance import check_tm  # written in parallel; present once integrated

    for path in playground("tm_valid", exact=False):
        diags = Diagnostics()
        doc = load_path(str(path), diags)
        assert doc is not None
        check_tm(doc, diags)
        assert not diags.has_errors, (path.name, diags.errors())
    for path in playground("tm_invalid", exact=True):  # names unavailableParent.json
        diags = Diagnostics()
        doc = load_path(str(path), diags)
        assert doc is not None
        check_tm(doc, diags)
        schema_failed = diags.has_errors
        assert schema_failed is (path.name != "unavailableParent.json"), path.name
        if not schema_failed:
            assert instantiate(doc, {}, diags) is None and diags.has_errors


# ---------------------------------------------------------------------------------------------------------
# never a traceback

_json = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from(["{{A}}", "x {{B}} y", "#/properties/a", "lib.tm.json#/x", "/properties/a", "tm:extends"])
    | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(
            st.sampled_from(["a", "{{A}}", "tm:ref", "rel", "href", "forms", "type", "tm:optional"])
            | st.text(max_size=4),
            children,
            max_size=4,
        )
    ),
    max_leaves=20,
)
_members = st.dictionaries(
    st.sampled_from(
        [
            "@context",
            "@type",
            "title",
            "properties",
            "actions",
            "events",
            "links",
            "tm:optional",
            "version",
            "security",
        ]
    ),
    _json,
    max_size=6,
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    members=_members,
    values=st.dictionaries(st.sampled_from(["A", "B", "robotName"]), _json, max_size=3),
    include=st.booleans() | st.lists(st.text(max_size=6), max_size=2),
)
def test_instantiate_never_raises(members: dict[str, Any], values: dict[str, Any], include: Any) -> None:
    doc = from_text({"@type": "tm:ThingModel", **members})
    diags = Diagnostics()
    td = instantiate(doc, values, diags, include_optional=include)
    assert (td is None) == diags.has_errors
    if td is not None:
        json.dumps(td)
    check_against_model(from_text({"title": "t", **members}, "t.td.json"), Diagnostics())
