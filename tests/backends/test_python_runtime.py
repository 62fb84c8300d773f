"""The run-time modules the Python backends copy unchanged into their packages (`backends/*/verbatim/`) are
checked here as what they are, code: ruff (their own target version), mypy --strict and pyright --strict, each
backend's in the package layout it is copied into (rospy's against its own rospy/genpy stubs). Pyright also
checks the golden RB-1 packages in generated/ whole, with their message stubs.

Pyright comes from npm, pinned: `bash .ci/setup-pyright.sh` installs it into .cache/pyright.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.ros2.common import require_ros2
from tests.tools import require

VENV_BIN = Path(sys.executable).parent
BACKENDS = REPO / "td2adaptor" / "backends"
SHARED = BACKENDS / "_python" / "verbatim"
PYRIGHT = REPO / ".cache" / "pyright" / "node_modules" / ".bin" / "pyright"
PACKAGE = "robotnik_rb_1_adaptor"
VERBATIM_DIRS = sorted(p for p in BACKENDS.glob("*/verbatim") if any(p.rglob("*.py")))


def _run(args: list[str | Path], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(a) for a in args], cwd=cwd, capture_output=True, text=True, timeout=300)


def _package(tmp: Path, *runtime: Path) -> Path:
    """A package `pkg` as the backend lays it out: its runtime modules next to the shared modules."""
    pkg = tmp / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("", encoding="utf-8")
    for module in (*runtime, *SHARED.glob("*.py")):
        shutil.copy(module, pkg / module.name)
    return pkg


def pyright() -> Path:
    """The pinned pyright, installed by .ci/setup-pyright.sh when node and npm are there."""
    require("node", "apt install nodejs")
    require("npm", "apt install npm")
    if not PYRIGHT.exists():
        setup = _run(["bash", REPO / ".ci" / "setup-pyright.sh"], REPO)
        assert setup.returncode == 0, setup.stderr
    return PYRIGHT


def _pyright(config: dict[str, object], where: Path, python: str) -> None:
    (where / "pyrightconfig.json").write_text(json.dumps(config), encoding="utf-8")
    proc = _run([pyright(), "--pythonpath", python, "-p", where / "pyrightconfig.json"], where)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "0 errors, 0 warnings" in proc.stdout, proc.stdout


# rospy, genpy and the message modules are checked against stubs only (their sources are elsewhere, or not
# built yet): a stub without a source is expected, not a finding
STRICT = {"typeCheckingMode": "strict", "pythonVersion": "3.10", "reportMissingModuleSource": False}


def test_there_are_verbatim_modules() -> None:
    assert [p.parent.name for p in VERBATIM_DIRS] == ["_python", "rclpy", "rospy"]


@pytest.mark.parametrize("directory", VERBATIM_DIRS, ids=lambda p: p.parent.name)
def test_verbatim_modules_are_ruff_clean(directory: Path) -> None:
    for args in (["check", "--no-cache", "."], ["format", "--check", "--no-cache", "."]):
        proc = _run([VENV_BIN / "ruff", *args], directory)
        assert proc.returncode == 0, proc.stdout + proc.stderr


def test_rclpy_runtime_is_mypy_and_pyright_strict_clean(tmp_path: Path) -> None:
    require_ros2()  # rclpy's own annotations
    _package(tmp_path, BACKENDS / "rclpy" / "verbatim" / "runtime.py")
    proc = _run([VENV_BIN / "mypy", "--strict", "--cache-dir", tmp_path / ".mypy", "pkg"], tmp_path)
    assert proc.returncode == 0, proc.stdout
    _pyright({**STRICT, "include": ["pkg"]}, tmp_path, sys.executable)


def test_rospy_runtime_is_mypy_and_pyright_strict_clean_against_its_stubs(tmp_path: Path) -> None:
    _package(tmp_path, BACKENDS / "rospy" / "verbatim" / "_runtime.py", BACKENDS / "rospy" / "verbatim" / "_actions.py")
    stubs = BACKENDS / "rospy" / "verbatim" / "stubs"
    mypy = [VENV_BIN / "mypy", "--strict", "--python-version", "3.10", "--cache-dir", tmp_path / ".mypy", "pkg"]
    proc = subprocess.run(
        [str(a) for a in mypy], cwd=tmp_path, capture_output=True, text=True, env={"MYPYPATH": str(stubs)}
    )
    assert proc.returncode == 0, proc.stdout
    _pyright({**STRICT, "include": ["pkg"], "stubPath": str(stubs)}, tmp_path, sys.executable)


def test_generated_rclpy_package_is_pyright_strict_clean(tmp_path: Path) -> None:
    require_ros2()
    root = REPO / "generated" / "rclpy" / PACKAGE
    include = [str(root / PACKAGE), str(root / "launch")]  # the launch file against the launch/launch_ros stubs
    _pyright({**STRICT, "include": include, "stubPath": str(root / "stubs")}, tmp_path, sys.executable)


def test_generated_rospy_package_is_pyright_strict_clean(tmp_path: Path) -> None:
    root = REPO / "generated" / "rospy" / PACKAGE
    _pyright({**STRICT, "include": [str(root / "src")], "stubPath": str(root / "stubs")}, tmp_path, sys.executable)
