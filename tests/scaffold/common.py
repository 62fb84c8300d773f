"""Shared by the scaffold tests: running `td2adaptor scaffold`, checking what it wrote, comparing it with the
hand-written RB-1 TD (examples/robotnik_rb1/td.json)."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.diagnostics import Severity
from tests.conftest import EXAMPLE, REPO

INTERFACES = EXAMPLE / "interfaces"

#: the RB-1 example's hand-chosen names for what the scaffold names after the graph (example → scaffold):
#: the intended difference; `--merge` into the example keeps the example's names
RENAMED = {"availability": "state", "poseMarker": "arPoseMarker", "door": "command"}
#: binding members the graph cannot show and the example sets by hand (see docs/scaffold.md)
NOT_FROM_GRAPH = {
    "ros2": {"door": {"rosv:qos"}},  # DDS discovery reports no history depth: the example's depth 1
    "ros1": {"door": {"rosv:qos", "rosv:latch"}},  # the master knows no QoS, and latching is the publisher's
}

#: fields the scaffold gives an `enum` (from the .msg's constants named after them) where the example has a
#: plain type (see docs/scaffold.md): ROS name -> fields of its message
ENUMS_ADDED = {
    "/{{robotName}}/robot_local_control/state": {"robot_state", "control_state", "operation_state"},
}


@dataclass
class Scaffolded:
    code: int
    stderr: str
    doc: dict[str, Any] | None


def scaffold(args: Sequence[str], out: Path, env: dict[str, str] | None = None, timeout: float = 120) -> Scaffolded:
    """`td2adaptor scaffold ARGS -o OUT` in a child process."""
    proc = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "scaffold", *args, "-o", str(out)],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout,
    )  # fmt: skip
    assert "Traceback" not in proc.stderr, proc.stderr
    doc = json.loads(out.read_text(encoding="utf-8")) if proc.returncode == 0 else None
    return Scaffolded(proc.returncode, proc.stderr, doc)


def compiled_errors(doc: dict[str, Any], tmp: Path, interfaces: Sequence[Path] = (INTERFACES,)) -> list[str]:
    """Errors of `td2adaptor validate` on `doc` (the compiler the CLI runs)."""
    path = tmp / "check.td.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    result = td2adaptor.compile(path, interfaces=list(interfaces))
    return [f"{d.code} {d.message} {d.pointer}" for d in result.diagnostics if d.severity is Severity.ERROR]


class W3CSchemaMissing(UserWarning):
    """The official W3C schema is not installed: the W3C check of a test did not run (its other checks did)."""


def w3c_errors(doc: dict[str, Any]) -> list[str]:
    """Violations of the official W3C TD (or TM) JSON Schema (tests/wot_corpus: ../shared or pinned npm).

    Without the schema (.ci/setup-wot.sh installs it) only this check is skipped, not the whole test: it
    gives no violations and a W3CSchemaMissing warning in the test report."""
    from jsonschema import Draft7Validator, FormatChecker

    from tests import wot_corpus

    name = "tm-schema-v1.1.json" if doc.get("@type") == "tm:ThingModel" else "td-schema-v1.1.json"
    try:
        schema = wot_corpus.official_json(name)
    except pytest.skip.Exception as missing:
        warnings.warn(W3CSchemaMissing(f"W3C schema check not run: {missing.msg}"), stacklevel=2)
        return []
    validator = Draft7Validator(schema, format_checker=FormatChecker())
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message[:200]}" for e in validator.iter_errors(doc)]


def without_texts(schema: Any) -> Any:
    """A data schema without title/description/unit (the example's are hand-written, the scaffold's come from
    .msg comments; property names are kept)."""
    if isinstance(schema, list):
        return [without_texts(s) for s in schema]
    if not isinstance(schema, dict):
        return schema
    out = {}
    for key, value in schema.items():
        if key in ("title", "description", "unit"):
            continue
        if key == "properties" and isinstance(value, dict):
            out[key] = {k: without_texts(v) for k, v in value.items()}
        else:
            out[key] = without_texts(value)
    return out


def _by_rosname(doc: dict[str, Any]) -> dict[str, tuple[str, str, dict[str, Any]]]:
    return {
        aff["forms"][0]["rosv:name"]: (section, name, aff)
        for section in ("properties", "actions", "events")
        for name, aff in (doc.get(section) or {}).items()
    }


def compare_with_example(doc: dict[str, Any], example: dict[str, Any], distro: str) -> None:
    """Same affordances (by ROS name), names (but RENAMED), kinds, bindings, schemas and procedure links."""
    mine, theirs = _by_rosname(doc), _by_rosname(example)
    assert sorted(mine) == sorted(theirs)
    for rosname, (section, name, aff) in theirs.items():
        my_section, my_name, my_aff = mine[rosname]
        assert (my_section, my_name) == (section, RENAMED.get(name, name)), rosname
        skip = NOT_FROM_GRAPH[distro].get(name, set())
        form, my_form = aff["forms"][0], my_aff["forms"][0]
        expected = {k: v for k, v in form.items() if k not in skip and k != "href"}
        assert {k: v for k, v in my_form.items() if k not in skip and k != "href"} == expected, rosname
        # the href is relative to the robot namespace, as in the example
        assert my_form["href"] == form["href"], rosname
        for key in ("input", "output", "safe", "idempotent", "rosv:procedure", "readOnly", "writeOnly", "observable"):
            assert without_texts(my_aff.get(key)) == without_texts(aff.get(key)), (rosname, key)
        if section == "properties":
            schema = {k: aff.get(k) for k in ("type", "properties")}
            mine_schema = without_texts({k: my_aff.get(k) for k in ("type", "properties")})
            for field in ENUMS_ADDED.get(rosname, ()):
                assert mine_schema["properties"][field].pop("enum"), (rosname, field)
            assert mine_schema == without_texts(schema)
        component = aff["rosv:component"]
        if name in RENAMED:
            component = RENAMED[name][:1].upper() + RENAMED[name][1:] + "Component"
        assert my_aff["rosv:component"] == component, rosname


def example_td() -> dict[str, Any]:
    return json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
