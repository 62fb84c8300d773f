"""Several TDs into one events output (issue 13): the robots of one system, the RB-1 and the warehouse door, each
get their folder OUT/events/<package>/, next to an index; every `$id`, `$ref` and link resolves from the written
files alone; a package name two TDs share still collides (GEN805)."""

from __future__ import annotations

import json
import posixpath
import re
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

import td2adaptor
from td2adaptor.backends import registry
from td2adaptor.backends.events import generator as backend
from td2adaptor.cli.main import cli
from td2adaptor.compiler.build import generate, target
from td2adaptor.diagnostics import Severity
from td2adaptor.generation.backend import GeneratedTree
from td2adaptor.generation.emit import MANIFEST
from td2adaptor.model.events import SCHEMA_BASE
from tests.backends.events.test_events import ENVELOPE, FEEDBACK, _refs, _resolve, tree_of
from tests.conftest import EXAMPLE, REPO
from tests.runtime.rb1 import compile_td

RB1 = EXAMPLE / "td.json"
DOOR = REPO / "examples" / "warehouse" / "door.td.json"
IFACES = [EXAMPLE / "interfaces"]
PACKAGES = {"robotnik_rb_1_adaptor": RB1, "warehouse_door_adaptor": DOOR}


def _written(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """OUT/events/ as written for the RB-1 and the door, paths relative to it (the manifest left out)."""
    out = tmp_path_factory.mktemp("two")
    outcome = generate([target([RB1, DOOR], backends=["events"], output=out, interfaces=IFACES)], use_cache=False)
    assert outcome.ok, [(d.code, d.message) for d in outcome.diagnostics]
    written = _written(out / "events")
    del written[MANIFEST]
    return written


def doc(files: dict[str, bytes], path: str) -> Any:
    return json.loads(files[path])


def test_each_package_gets_the_folder_one_td_alone_gets(files: dict[str, bytes]) -> None:
    assert {p.partition("/")[0] for p in files} == {"README.md", *PACKAGES}
    for package, td in PACKAGES.items():
        alone = tree_of(compile_td(td))  # the same bytes as when the TD is generated on its own
        assert {p[len(package) + 1 :]: d for p, d in files.items() if p.startswith(package + "/")} == alone


def test_the_index_lists_every_package_in_name_order(files: dict[str, bytes]) -> None:
    index = files["README.md"].decode()
    rows = [line for line in index.splitlines() if line.startswith("| [")]
    assert re.findall(r"^\| \[`(\w+)`\]", index, re.MULTILINE) == sorted(PACKAGES)
    assert "| Robotnik RB-1 |" in rows[0] and "| Warehouse Door |" in rows[1]
    for package in PACKAGES:  # and each package README links back to it
        assert "[the index](../README.md)" in files[f"{package}/README.md"].decode()


def test_schema_ids_mirror_the_layout_and_the_files_alone_validate_both_robots(files: dict[str, bytes]) -> None:
    from referencing import Registry, Resource

    schemas = {p: doc(files, p) for p in files if p.endswith(".schema.json")}
    for path, schema in schemas.items():
        Draft202012Validator.check_schema(schema)
        assert schema["$id"] == SCHEMA_BASE + path  # hence relative $refs resolve between the files
    assert len({s["$id"] for s in schemas.values()}) == len(schemas)  # no id is shared between packages
    registry = Registry().with_resources((s["$id"], Resource.from_contents(s)) for s in schemas.values())

    def validator(path: str, pointer: str = "") -> Any:
        return Draft202012Validator({"$ref": SCHEMA_BASE + path + pointer}, registry=registry)

    rb1 = "robotnik_rb_1_adaptor/schemas/"
    feedback = validator(rb1 + "GoToComponent.events.schema.json", "#/$defs/gotoRun.feedback")
    assert feedback.is_valid(FEEDBACK)
    assert not feedback.is_valid({**FEEDBACK, "time": "yesterday"})  # the envelope, via the relative $ref
    command = validator("warehouse_door_adaptor/schemas/DoorComponent.events.schema.json", "#/$defs/command.write")
    assert command.is_valid({"payload": {"data": 1.0}})
    assert not command.is_valid({"payload": {"data": 2.0}})  # the door TD's maximum
    assert not command.is_valid({"payload": {"data": 1.0}, "robot": "a/b"})  # the door's own envelope
    for package in PACKAGES:
        status = validator(f"{package}/schemas/status.schema.json")
        assert status.is_valid({"type": "status", **ENVELOPE, "payload": {"state": "online"}})
        assert not status.is_valid({"type": "status", **ENVELOPE, "payload": {"state": "sleepy"}})


def test_every_reference_and_link_resolves_from_the_files(files: dict[str, bytes]) -> None:
    for package in PACKAGES:
        api_path = f"{package}/asyncapi.json"
        api = doc(files, api_path)
        assert api["asyncapi"] == "3.1.0"
        for ref in _refs(api):
            assert _resolve(files, api_path, api, ref) is not None, ref
        for message in api["components"]["messages"].values():
            schema = _resolve(files, api_path, api, message["payload"]["schema"]["$ref"])
            assert schema["title"] == message["title"]
    for path in (p for p in files if p.endswith(".schema.json")):
        schema = doc(files, path)
        for ref in _refs(schema):  # members of the envelope, next to the file
            assert ref.startswith("envelope.schema.json#/properties/"), ref
            assert _resolve(files, path, schema, ref)["description"]
    readmes = [p for p in files if p.endswith("README.md")]
    assert len(readmes) == 1 + len(PACKAGES)
    for path in readmes:
        links = re.findall(r"\]\(([^)]+)\)", files[path].decode())
        assert links
        for link in links:
            assert posixpath.normpath(posixpath.join(posixpath.dirname(path), link.partition("#")[0])) in files, link


def test_the_door_exposed_td_passes_our_validator(files: dict[str, bytes], tmp_path: Path) -> None:
    path = tmp_path / "door.mqtt.json"
    path.write_bytes(files["warehouse_door_adaptor/td.mqtt.json"])
    result = td2adaptor.compile(path, values={"robotName": "door1", "mqttBroker": "mqtt://127.0.0.1:1883"})
    assert not [(d.code, d.message) for d in result.diagnostics if d.severity is Severity.ERROR]


def test_the_order_of_the_tds_does_not_matter(files: dict[str, bytes], tmp_path: Path) -> None:
    outcome = generate([target([DOOR, RB1], backends=["events"], output=tmp_path, interfaces=IFACES)])
    assert outcome.ok
    written = _written(tmp_path / "events")
    del written[MANIFEST]
    assert written == files


def test_one_package_name_for_two_tds_still_collides(tmp_path: Path) -> None:
    job = target([RB1, DOOR], backends=["events"], output=tmp_path, interfaces=IFACES, package_name="same")
    outcome = generate([job])
    assert not outcome.ok and not (tmp_path / "events").exists()
    collisions = {d.message for d in outcome.diagnostics if d.code == "GEN805"}
    readme = tmp_path / "events" / "same" / "README.md"
    assert f"two inputs generate different {readme} (the other: {RB1})" in collisions


def test_the_index_keeps_hostile_titles_as_text() -> None:
    evil = "Evil | row |\n| injected | row | x |\n<script>x</script> [link](http://example.invalid)"
    tree = GeneratedTree()
    tree.add("evil_adaptor/td.mqtt.json", json.dumps({"title": evil}))
    index = backend.finish(tree).files["README.md"].decode()
    assert "| injected |" not in index and "<script>" not in index
    assert re.search(r"(?<!\\)\]\(http", index) is None and "\\[link\\](http" in index  # no link, escaped text
    assert all(line.count("|") - line.count("\\|") == 4 for line in index.splitlines() if line.startswith("| ["))


def _cli(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.output


#: all: the mROS tree stated to take the RB-1 types' TCPROS headers (MROS914 otherwise)
ALL = ["-b", "all", "--partial", "--option", "mros.tcpros_header_max=8192"]


@pytest.mark.parametrize("backends", [["-b", "events"], ALL], ids=["events", "all"])
def test_gen_then_check_of_two_tds(backends: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    args = [str(RB1), str(DOOR), "-I", str(IFACES[0]), *backends, "-o", "out", "--no-cache"]
    code, output = _cli("gen", *args)
    assert code == 0, output
    assert "GEN805" not in output
    assert sorted(p.name for p in (tmp_path / "out" / "events").iterdir()) == sorted([MANIFEST, "README.md", *PACKAGES])
    if "all" in backends:  # the other backends put each package in its folder too
        for name in (b for b in registry.builtin() if b != "events"):
            assert {p.name for p in (tmp_path / "out" / name).iterdir() if p.is_dir()} == set(PACKAGES), name
    assert _cli("check", *args) == (0, "td2adaptor check: generated code is current\n")
