"""Each golden case's expected output is valid output, not just stable output: the Python packages pass ruff
(check and format, with the ruff.toml they ship), the event schemas are JSON Schemas and the exposed TD passes
td2adaptor's validator, the mROS application is C++98 with every warning an error. The checks run on the
output whole (`materialized`: the case's files with its verbatim ones put back), made once per session."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator

import td2adaptor
from td2adaptor.backends import registry
from td2adaptor.backends.mros import lint as mros_lint
from td2adaptor.diagnostics import Severity
from tests.backends.events.schemawalk import untyped
from tests.backends.mros import build as mros_build
from tests.golden.goldens import CASES, materialize, tomllib
from tests.tools import require

VENV_BIN = Path(sys.executable).parent


def _packages(backend: str) -> list[Path]:
    return sorted(p for p in CASES.glob(f"*/expected/{backend}/*") if p.is_dir())


PYTHON = _packages("rclpy") + _packages("rospy")
EVENTS = _packages("events")
MROS = _packages("mros")


def _id(path: Path) -> str:
    return path.relative_to(CASES).as_posix()


@pytest.fixture(scope="session")
def materialized(tmp_path_factory: pytest.TempPathFactory) -> Callable[[Path], Path]:
    """A generated package of a case, whole (the verbatim files the golden records by hash put back), in a
    scratch folder: made once per session for every test that reads it."""
    made: dict[Path, Path] = {}
    scratch = tmp_path_factory.mktemp("case-output")

    def package(pkg: Path) -> Path:
        root = pkg.parent  # the backend's output directory: the verbatim index is there
        if root not in made:
            made[root] = materialize(root, scratch / root.relative_to(CASES).as_posix().replace("/", "-"))
        return made[root] / pkg.name

    return package


def _asked(case: Path) -> set[str]:
    """The backends the case's configuration names (`all`: the shipped ones)."""
    with (case / "td2adaptor.toml").open("rb") as fh:
        targets = tomllib.load(fh)["target"]
    named = {b for t in targets for b in t.get("backends", ["all"])}
    return (named - {"all"}) | (set(registry.builtin()) if "all" in named else set())


def test_every_case_has_the_output_of_the_backends_it_asks_for() -> None:
    """Derived from the registry and the cases' configurations, not a list of backends: a case that a backend
    cannot represent names the others instead (and its configuration says why)."""
    for case in sorted(p for p in CASES.iterdir() if p.is_dir()):
        assert {p.name for p in (case / "expected").iterdir() if p.is_dir()} == _asked(case), case.name


@pytest.mark.parametrize("golden", PYTHON, ids=[_id(p) for p in PYTHON])
def test_python_package_passes_ruff(golden: Path, materialized: Callable[[Path], Path]) -> None:
    pkg = materialized(golden)
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


@pytest.mark.parametrize("golden", MROS, ids=[_id(p) for p in MROS])
def test_mros_application_is_cxx98(golden: Path, tmp_path: Path, materialized: Callable[[Path], Path]) -> None:
    """In a copy, with the kernel_cfg.h the TOPPERS configurator would make from app.cfg."""
    require(mros_build.HOST_CXX, ".ci/setup-mros.sh")
    root = tmp_path / golden.name
    shutil.copytree(materialized(golden), root)
    (root / "kernel_cfg.h").write_text(mros_lint.kernel_cfg_h((root / "app.cfg").read_text(encoding="utf-8")))
    mros_build.run([mros_build.HOST_CXX, *mros_build.HOST_SYNTAX, *mros_build.includes(root), str(root / "app.cpp")])
