"""td2adaptor's own code is ruff- and mypy --strict-clean: the checks run as part of the test suite, so a red
lint is a red build. (Generated code and the backends' verbatim files have tests of their own.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.conftest import REPO

BIN = Path(sys.executable).parent
TREES = ["td2adaptor", "tests", "bench", "examples"]


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=600)


def test_ruff_check_and_format() -> None:
    check = _run(str(BIN / "ruff"), "check", "--no-cache", *TREES)
    assert check.returncode == 0, check.stdout + check.stderr
    fmt = _run(str(BIN / "ruff"), "format", "--check", "--no-cache", *TREES)
    assert fmt.returncode == 0, fmt.stdout + fmt.stderr


def test_mypy_strict(tmp_path: Path) -> None:
    # the configuration in pyproject.toml: strict, td2adaptor/ and examples/warehouse/
    proc = _run(str(BIN / "mypy"), "--cache-dir", str(tmp_path / "mypy-cache"))
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_the_package_ships_its_type_information() -> None:
    assert (REPO / "td2adaptor" / "py.typed").is_file()
