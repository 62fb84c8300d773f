"""Property test: random mutations of the RB-1 TDs never raise, and every diagnostic is located."""

from __future__ import annotations

import copy
import io
import json
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import td2adaptor
from td2adaptor.compiler.pipeline import Result
from td2adaptor.diagnostics import Severity, pointer_tokens
from tests.conftest import EXAMPLE

BASES = {name: json.loads((EXAMPLE / name).read_text()) for name in ("td.json", "td.reference-dialect.json")}
INTERFACES = [EXAMPLE / "interfaces"]

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=12)
    # lone surrogates: json.dumps writes them as `\\udXXX` escapes the loader must refuse, not pass on
    | st.text(st.characters(min_codepoint=0xD7F0, max_codepoint=0xE010, exclude_categories=()), max_size=3),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=8), children, max_size=3),
    max_leaves=8,
)
weird_names = st.sampled_from(
    [
        "",
        "class",
        "9x",
        "a b",
        "__init__",
        "gotoRun",
        "x" * 300,
        "ünïcode",
        "a/b",
        "{{robotName}}",
        "../../etc",
        "half\udc00",
    ]
)
weird_types = st.sampled_from(
    [
        "",
        "std_msgs/msg/Nope",
        "std_msgs/Float64",
        "nopkg/srv/Trigger",
        "a.b.C",
        "std_srvs/srv/Trigger",
        "pkg/x/Y",
        "//",
    ]
)


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, (*prefix, i))
    return out


PATHS = {name: _paths(td)[1:] for name, td in BASES.items()}


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    name = draw(st.sampled_from(sorted(BASES)))
    td = copy.deepcopy(BASES[name])
    for _ in range(draw(st.integers(1, 4))):
        path = draw(st.sampled_from(PATHS[name]))
        parent: Any = td
        try:
            for key in path[:-1]:
                parent = parent[key]
            last = path[-1]
            parent[last]  # noqa: B018 - the path may be gone after an earlier mutation
        except (KeyError, IndexError, TypeError):
            continue
        op = draw(st.sampled_from(["delete", "replace", "retype", "rename", "type"]))
        if op == "delete":
            del parent[last]
        elif op == "replace":
            parent[last] = draw(json_values)
        elif op == "retype":
            value = parent[last]
            parent[last] = [value] if not isinstance(value, list) else {"x": value}
        elif op == "rename" and isinstance(parent, dict):
            parent[draw(weird_names)] = parent.pop(last)
        elif op == "type" and isinstance(parent, dict):
            parent["rosv:type" if name == "td.json" else "ros:serviceType"] = draw(weird_types)
    return json.dumps(td).encode()


def _check(result: Result) -> None:
    for d in result.diagnostics:
        assert d.pointer == "" or d.pointer.startswith("/"), d
        pointer_tokens(d.pointer)
        assert d.file, d
        if d.severity is Severity.ERROR and d.code.startswith(("ROS", "TD1", "XC")):
            assert d.line is not None, d
    if result.model is None:
        assert any(d.severity is Severity.ERROR for d in result.diagnostics)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutations_never_raise(data: bytes) -> None:
    _check(td2adaptor.compile("-", stdin=io.BytesIO(data), interfaces=INTERFACES))


@settings(max_examples=40, deadline=None)
@given(st.binary(max_size=200) | json_values.map(lambda v: json.dumps(v).encode()))
def test_arbitrary_bytes_never_raise(data: bytes) -> None:
    result = td2adaptor.compile("-", stdin=io.BytesIO(data))
    _check(result)
    assert result.model is None or result.model.components == ()


def test_unknown_type_mutation_always_reports() -> None:
    td = copy.deepcopy(BASES["td.json"])
    td["actions"]["pickRun"]["forms"][0]["rosv:type"] = "robot_local_control_msgs/srv/PickPetitionX"
    result = td2adaptor.compile("-", stdin=io.BytesIO(json.dumps(td).encode()), interfaces=INTERFACES)
    (diag,) = [d for d in result.diagnostics if d.code == "ROS423"]
    assert diag.pointer == "/actions/pickRun/forms/0/rosv:type" and diag.line is not None
