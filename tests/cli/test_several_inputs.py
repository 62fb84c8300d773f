"""validate and types take the inputs gen and check take: several TDs, each compiled alone, and RosClasses config
files merged into one input (`compiler.units.compile_units`). They used to refuse two TDs with TD008 while gen
generated them, so validate and gen disagreed on what is an error.
"""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner

from td2adaptor.cli.main import cli
from tests.conftest import EXAMPLE, REPO

IFACE = ["-I", str(EXAMPLE / "interfaces")]
RB1 = str(EXAMPLE / "td.json")
DOOR = str(REPO / "examples" / "warehouse" / "door.td.json")
LEGACY = REPO / "tests" / "data" / "legacy"
CONFIG = [str(LEGACY / "service.json"), str(LEGACY / "topic.json")]


def _invoke(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_validate_two_tds_as_gen_takes_them() -> None:
    code, _, err = _invoke("validate", RB1, DOOR, *IFACE, "--no-cache")
    assert code == 0, err
    assert "TD008" not in err
    assert err.splitlines()[-1].startswith(f"{RB1}, {DOOR}: valid")


def test_validate_reports_each_files_diagnostics_and_one_verdict(tmp_path: Path) -> None:
    broken = tmp_path / "broken.td.json"
    td = json.loads(Path(DOOR).read_text())
    del td["security"]  # a TD 1.1 error in the second file only
    broken.write_text(json.dumps(td))
    code, out, _ = _invoke("validate", RB1, str(broken), *IFACE, "--format", "json", "--no-cache")
    assert code == 1
    doc = json.loads(out)
    assert not doc["valid"] and doc["errors"] >= 1
    errors = {Path(d["file"]).name for d in doc["diagnostics"] if d["severity"] == "error"}
    assert errors == {"broken.td.json"}
    assert all(d["code"] != "TD008" for d in doc["diagnostics"])


def test_validate_merges_rosclasses_files_and_keeps_a_td_alone() -> None:
    code, _, err = _invoke("validate", *CONFIG, DOOR, *IFACE, "--no-cache")
    assert code == 0, err
    assert "TD008" not in err
    # the config files are one input: one package, as migrate and gen make of them
    code, out, err = _invoke("types", *CONFIG, DOOR, *IFACE, "--no-cache")
    assert code == 0, err
    packages = [line for line in out.splitlines() if line.startswith("package ")]
    assert packages == ["package ros_edge_node_adaptor", "package warehouse_door_adaptor"]


def test_types_of_two_tds() -> None:
    code, out, err = _invoke("types", RB1, DOOR, *IFACE, "--no-cache")
    assert code == 0, err
    packages = [line for line in out.splitlines() if line.startswith("package ")]
    assert packages == ["package robotnik_rb_1_adaptor", "package warehouse_door_adaptor"]
    code, out, err = _invoke("types", RB1, DOOR, *IFACE, "--format", "json", "--no-cache")
    assert code == 0, err
    doc = json.loads(out)
    assert [t["package"] for t in doc["types"]] == ["robotnik_rb_1_adaptor", "warehouse_door_adaptor"]
    # one input keeps its object, as before
    code, out, _ = _invoke("types", DOOR, *IFACE, "--format", "json", "--no-cache")
    assert json.loads(out)["types"]["package"] == "warehouse_door_adaptor"
