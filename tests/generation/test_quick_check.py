"""`td2adaptor check` with no argument (the pre-commit no-op) answers "current" without loading click, and
says exactly what the click command says; every other outcome still goes through the click command."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import EXAMPLE

REPO = Path(__file__).resolve().parents[2]
#: the console script's own entry point, with a line at exit saying whether click was loaded
_ENTRY = (
    "import atexit, sys\n"
    "atexit.register(lambda: print('click loaded:', 'click' in sys.modules))\n"
    "from td2adaptor.cli import main\n"
    "main()\n"
)


@pytest.fixture
def project(tmp_path: Path) -> Path:
    shutil.copytree(EXAMPLE, tmp_path / "rb1", ignore=shutil.ignore_patterns("sim"))
    (tmp_path / "pyproject.toml").write_text(
        '[project]\nname = "robots"\n\n[tool.td2adaptor]\noutput = "out"\n\n'
        '[[tool.td2adaptor.target]]\ntds = ["rb1/td.json"]\nbackends = ["events"]\ninterfaces = ["rb1/interfaces"]\n'
    )
    return tmp_path


def _td2adaptor(project: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run(
        [sys.executable, "-c", _ENTRY, *args], cwd=project, capture_output=True, text=True, env=env, timeout=120
    )


def test_current_without_click(project: Path) -> None:
    assert _td2adaptor(project, "gen").returncode == 0
    done = _td2adaptor(project, "check")
    assert (done.returncode, done.stderr, done.stdout) == (
        0,
        "td2adaptor check: generated code is current\n",
        "click loaded: False\n",
    )
    # the click command (any option takes it) says the same
    full = _td2adaptor(project, "check", "--format", "human")
    assert (full.returncode, full.stderr, full.stdout) == (0, done.stderr, "click loaded: True\n")


def test_stale_goes_through_the_click_command(project: Path) -> None:
    assert _td2adaptor(project, "gen").returncode == 0
    td = json.loads((project / "rb1" / "td.json").read_text())
    td["properties"]["door"]["description"] = "the door, described anew"
    (project / "rb1" / "td.json").write_text(json.dumps(td))
    done = _td2adaptor(project, "check")
    assert done.returncode == 1 and "generated code is stale" in done.stderr, done.stderr
    assert done.stdout == "click loaded: True\n"


def test_no_configuration_is_still_a_usage_error(tmp_path: Path) -> None:
    done = _td2adaptor(tmp_path, "check")
    assert done.returncode == 2 and "no TD given" in done.stderr and "Traceback" not in done.stderr
