"""One parse per input per command, and `--package-name` checked and applied once (issue 34).

A `gen` walk used to parse its TD up to three times: to compile it, then twice more to give the backends'
diagnostics a line (once to see whether it was a RosClasses file, once to locate). With several inputs,
each was parsed once more to group them. The package name was checked by lowering and by generation, and
applied by lowering, by generation and by every backend. The counts here are of the real parser's calls.
"""

from __future__ import annotations

import dataclasses
import json
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from td2adaptor.compiler import build, units
from td2adaptor.compiler.build import generate, target
from td2adaptor.frontend import jsonsrc
from td2adaptor.lowering import rosnames
from tests.conftest import EXAMPLE, REPO

RB1 = EXAMPLE / "td.json"
TM = EXAMPLE / "rb1.tm.json"
DOOR = REPO / "examples" / "warehouse" / "door.td.json"
LEGACY = REPO / "tests" / "data" / "legacy"
CONFIG = [LEGACY / "service.json", LEGACY / "topic.json"]
IFACES = [EXAMPLE / "interfaces"]


@pytest.fixture
def parses(monkeypatch: pytest.MonkeyPatch) -> Iterator[Counter[str]]:
    """How often each file is parsed (by its resolved path), through the real parser."""
    counts: Counter[str] = Counter()
    real = jsonsrc.parse_json

    def counting(raw: bytes | str, name: str, diags: Any, **kw: Any) -> Any:
        path = kw.get("path")
        counts[str(Path(path).resolve()) if path is not None else name] += 1
        return real(raw, name, diags, **kw)

    monkeypatch.setattr(jsonsrc, "parse_json", counting)
    monkeypatch.setattr(jsonsrc, "_KEPT", {}, raising=False)  # nothing kept from an earlier test
    yield counts


def _resolved(*paths: Path) -> Counter[str]:
    return Counter({str(p.resolve()): 1 for p in paths})


def test_gen_of_a_td_whose_backends_report_parses_it_once(tmp_path: Path, parses: Counter[str]) -> None:
    # mROS cannot represent the RB-1: the warning that it was skipped is located in the TD after generation
    outcome = generate([target(RB1, output=tmp_path, interfaces=IFACES, partial=True)], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    (skipped,) = [d for d in outcome.diagnostics if d.code == "GEN807"]
    assert (skipped.file, skipped.pointer) == (str(RB1), "/properties/availability") and skipped.line
    assert parses == _resolved(RB1)


def test_gen_of_a_thing_model_parses_it_once(tmp_path: Path, parses: Counter[str]) -> None:
    job = target(TM, output=tmp_path, interfaces=IFACES, values={"robotName": "rb1"}, partial=True)
    outcome = generate([job], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    assert parses[str(TM.resolve())] == 1


def test_gen_of_two_tds_parses_each_once(tmp_path: Path, parses: Counter[str]) -> None:
    job = target([RB1, DOOR], output=tmp_path, interfaces=IFACES, partial=True)
    outcome = generate([job], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    assert parses == _resolved(RB1, DOOR)


def test_gen_of_rosclasses_files_parses_each_once(tmp_path: Path, parses: Counter[str]) -> None:
    job = target(CONFIG, backends=["rclpy", "mros"], output=tmp_path, interfaces=IFACES, partial=True)
    job = dataclasses.replace(job, options=(("mros.tcpros_header_max", 8192),))
    outcome = generate([job], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    # mROS's warning is pointed into service.json, where the user wrote the service
    (skipped,) = [d for d in outcome.diagnostics if d.code == "MROS900"]
    assert Path(str(skipped.file)).resolve() == CONFIG[0] and skipped.line
    assert parses == _resolved(*CONFIG)


def test_validate_of_two_tds_parses_each_once(parses: Counter[str]) -> None:
    result = CliRunner().invoke(cli, ["validate", str(RB1), str(DOOR), "-I", str(IFACES[0]), "--no-cache"])
    assert result.exit_code == 0, result.output
    assert parses == _resolved(RB1, DOOR)


def test_a_file_changed_after_it_was_looked_at_is_parsed_again(tmp_path: Path, parses: Counter[str]) -> None:
    config = tmp_path / "service.json"
    config.write_bytes(CONFIG[0].read_bytes())
    assert units.is_rosclasses(config)
    changed = json.loads(config.read_text())
    changed["RosClasses"] = []
    config.write_text(json.dumps(changed))
    doc = jsonsrc.load_path(str(config), jsonsrc.Diagnostics())
    assert doc is not None and doc.data == changed
    assert parses[str(config.resolve())] == 2


def test_the_package_name_is_checked_and_applied_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    checked: list[str] = []
    real = rosnames.package_name_problem

    def checking(name: str) -> str | None:
        checked.append(name)
        return real(name)

    monkeypatch.setattr(rosnames, "package_name_problem", checking)
    import td2adaptor.lowering.lower as lower_module

    monkeypatch.setattr(lower_module, "package_name_problem", checking)
    told: list[str | None] = []
    real_trees = build.generate_trees

    def trees(model: Any, names: Any, diags: Any, **kw: Any) -> Any:
        found = real_trees(model, names, diags, **kw)
        told.append(model.package_name)
        return found

    monkeypatch.setattr(build, "generate_trees", trees)
    seen: list[tuple[str, str | None]] = []
    from td2adaptor.backends import registry

    real_load = registry.load

    def load(name: str) -> Any:
        backend = real_load(name)

        class Spy:
            def __getattr__(self, attr: str) -> Any:
                return getattr(backend, attr)

            def generate(self, model: Any, options: Any, diags: Any) -> Any:
                seen.append((model.package_name, options.package_name))
                return backend.generate(model, options, diags)

        return Spy()  # type: ignore[return-value]

    monkeypatch.setattr(registry, "load", load)
    job = target(RB1, output=tmp_path, interfaces=IFACES, package_name="my_rb1", partial=True)
    outcome = generate([job], use_cache=False)
    assert outcome.ok, [d.message for d in outcome.diagnostics]
    assert checked == ["my_rb1"]  # by lowering, where the name becomes the model's
    assert told == ["my_rb1"]
    # every backend reads it from the model, and is not told it again beside the model
    assert seen and all(entry == ("my_rb1", None) for entry in seen)
    assert (tmp_path / "rclpy" / "my_rb1" / "package.xml").is_file()
