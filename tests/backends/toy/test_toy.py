"""The toy plug-in backend, installed as a third party's is (an entry point of an installed distribution):
found by the registry, run by `gen -b toy`, its own code in `explain` and in the documentation of its stage,
its golden case picked up by the golden tests; and nothing in td2adaptor names it."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from td2adaptor.backends import registry
from td2adaptor.cli.docs import documented
from td2adaptor.cli.main import cli
from td2adaptor.diagnostics.docs import render
from tests.conftest import EXAMPLE, REPO
from tests.golden.goldens import goldens

SITE = Path(__file__).resolve().parent / "site"  # what `pip install td2adaptor-toy` would have put on the path
GEN = ["gen", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "-b", "toy", "--no-cache"]


@pytest.fixture
def toy() -> Iterator[None]:
    """The toy installed for one test: its site folder on the path, the registry asked again; uninstalled after."""
    sys.path.insert(0, str(SITE))
    registry.modules.cache_clear()
    try:
        yield
    finally:
        sys.path.remove(str(SITE))
        registry.modules.cache_clear()


def test_the_registry_finds_it_through_its_entry_point(toy: None) -> None:
    assert registry.modules()["toy"] == "tests.backends.toy"
    assert "toy" in registry.available() and "toy" not in registry.builtin()
    (stage,) = registry.diagnostic_stages(["toy"])
    assert stage.prefix == "TOY1" and stage.backend == "toy"


def test_not_installed_it_is_not_there() -> None:
    assert "toy" not in registry.modules()


def test_gen_runs_it_and_reports_its_own_code(toy: None, tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, [*GEN, "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "warning TOY100: toy backend: 9 services listed by name only: gotoRun," in result.output
    text = (tmp_path / "toy" / "robotnik_rb_1_adaptor" / "endpoints.txt").read_text(encoding="utf-8")
    assert text.startswith("# Robotnik RB-1: the ROS endpoints of robotnik_rb_1_adaptor\n[GoToComponent]\n")


def test_a_fresh_process_with_the_distribution_installed_runs_it(tmp_path: Path) -> None:
    """No test machinery: the path as an installed distribution leaves it, and the command line."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), str(SITE)])}
    done = subprocess.run(
        [sys.executable, "-m", "td2adaptor", *GEN, "-o", str(tmp_path)], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "TOY100" in done.stdout + done.stderr and (tmp_path / "toy" / "robotnik_rb_1_adaptor").is_dir()


def test_explain_shows_its_code(toy: None) -> None:
    result = CliRunner().invoke(cli, ["explain", "TOY100"])
    assert result.exit_code == 0, result.output
    assert result.output.startswith("TOY100 (warning): services listed by name only")
    assert "stage: TOY1xx Toy backend (the test suite's plug-in) (tests/backends/toy)" in result.output


def test_its_stage_is_documented_with_it_and_not_in_td2adaptors_docs(toy: None) -> None:
    stages = registry.diagnostic_stages()
    assert "| `TOY100` | warning |" in render(stages)
    assert all(s.backend != "toy" for s in documented())
    assert "TOY100" not in (REPO / "docs" / "diagnostics.md").read_text(encoding="utf-8")


def test_its_golden_case_is_a_golden() -> None:
    assert "cases/toy" in {g.name for g in goldens()}
    assert (REPO / "tests" / "golden" / "cases" / "toy" / "expected" / "toy").is_dir()


def test_nothing_in_td2adaptor_names_it() -> None:
    """Everything the toy needs is the plug-in interface: no td2adaptor module knows it."""
    named = [p for p in (REPO / "td2adaptor").rglob("*.py") if "backends.toy" in p.read_text(encoding="utf-8")]
    assert named == []
