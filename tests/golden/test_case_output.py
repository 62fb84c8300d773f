"""Each golden case's expected output is valid output, not just stable output: the Python packages pass ruff
(check and format, with the ruff.toml they ship), the event schemas are JSON Schemas and the exposed TD passes
td2adaptor's validator, the mROS application is C++98 with every warning an error."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator

import td2adaptor
from td2adaptor.backends.mros import lint as mros_lint
from td2adaptor.diagnostics import Severity
from tests.backends.events.schemawalk import untyped
from tests.backends.mros import build as mros_build
from tests.golden.goldens import CASES, tomllib

VENV_BIN = Path(sys.executable).parent


def _packages(backend: str) -> list[Path]:
    return sorted(p for p in CASES.glob(f"*/expected/{backend}/*") if p.is_dir())


PYTHON = _packages("rclpy") + _packages("rospy")
EVENTS = _packages("events")
MROS = _packages("mros")


def _id(path: Path) -> str:
    return path.relative_to(CASES).as_posix()


def _asks_for_mros(case: Path) -> bool:
    """Whether the case's configuration names the mROS backend (or all backends)."""
    with (case / "td2adaptor.toml").open("rb") as fh:
        targets = tomllib.load(fh)["target"]
    return any({"all", "mros"} & set(t.get("backends", ["all"])) for t in targets)


def test_every_case_has_python_events_and_mros_output() -> None:
    cases = sorted(p.name for p in CASES.iterdir() if p.is_dir())
    for found in (PYTHON, EVENTS):
        assert sorted({p.relative_to(CASES).parts[0] for p in found}) == cases
    # every case that asks for mROS gets it (a case that mROS cannot represent leaves it out, and says why)
    assert sorted({p.relative_to(CASES).parts[0] for p in MROS}) == [c for c in cases if _asks_for_mros(CASES / c)]


@pytest.mark.parametrize("pkg", PYTHON, ids=[_id(p) for p in PYTHON])
def test_python_package_passes_ruff(pkg: Path) -> None:
    assert (pkg / "ruff.toml").is_file()
    for args in (["check", "--no-cache", "."], ["format", "--check", "--no-cache", "."]):
        proc = subprocess.run([str(VENV_BIN / "ruff"), *args], cwd=pkg, capture_output=True, text=True, check=False)
        assert proc.returncode == 0, f"ruff {' '.join(args)} in {pkg}:\n{proc.stdout}{proc.stderr}"


TM_VALUES = {"robotName": "rb1_base_a", "mqttBroker": "mqtt://127.0.0.1:1883"}


@pytest.mark.parametrize("out", EVENTS, ids=[_id(p) for p in EVENTS])
def test_event_schemas_and_exposed_td_are_valid(out: Path) -> None:
    schemas = sorted((out / "schemas").glob("*.json"))
    assert schemas
    for path in schemas:
        Draft202012Validator.check_schema(json.loads(path.read_text(encoding="utf-8")))
    assert json.loads((out / "asyncapi.json").read_text(encoding="utf-8"))["asyncapi"].startswith("3.")
    # the Thing Model of the fleet, instantiated for one robot on one broker
    result = td2adaptor.compile(out / "td.mqtt.json", values=TM_VALUES)
    errors = [(d.code, d.message, d.pointer) for d in result.diagnostics if d.severity is Severity.ERROR]
    assert not errors
    # every const or enum has a type (wotpy 0.18 refuses one without), in the schemas and in the model
    model = json.loads((out / "td.mqtt.json").read_text(encoding="utf-8"))
    for path in schemas:
        assert untyped(json.loads(path.read_text(encoding="utf-8"))) == [], path
    for section in ("properties", "actions", "events"):
        for name, affordance in model.get(section, {}).items():
            assert untyped(affordance) == [], f"{section}/{name}"


@pytest.mark.skipif(not mros_build.have(mros_build.HOST_CXX), reason="g++ not installed (.ci/setup-mros.sh)")
@pytest.mark.parametrize("app", MROS, ids=[_id(p) for p in MROS])
def test_mros_application_is_cxx98(app: Path, tmp_path: Path) -> None:
    """In a copy, with the kernel_cfg.h the TOPPERS configurator would make from app.cfg."""
    root = tmp_path / app.name
    shutil.copytree(app, root)
    (root / "kernel_cfg.h").write_text(mros_lint.kernel_cfg_h((root / "app.cfg").read_text(encoding="utf-8")))
    mros_build.run([mros_build.HOST_CXX, *mros_build.HOST_SYNTAX, *mros_build.includes(root), str(root / "app.cpp")])
