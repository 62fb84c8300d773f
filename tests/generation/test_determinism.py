"""Byte-identical output across runs with different hash seeds, working directories and listing orders."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

from tests.conftest import EXAMPLE, REPO

SHIM = Path(__file__).resolve().parent / "determinism"


def _tree_digest(root: Path) -> dict[str, str]:
    return {
        p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def test_ten_runs_are_byte_identical(tmp_path: Path) -> None:
    cli = Path(sys.executable).parent / "td2adaptor"
    digests = []
    for run in range(10):
        cwd = tmp_path / f"cwd{run}" / ("deep/" * (run % 3))
        cwd.mkdir(parents=True)
        out = tmp_path / f"out{run}"
        env = {
            **os.environ,
            "PYTHONHASHSEED": str(run * 7919 + 1),
            "TD2A_SHUFFLE_SEED": str(run),
            "PYTHONPATH": str(SHIM),
            "TD2ADAPTOR_NO_CACHE": "1",
        }
        proc = subprocess.run(
            [
                str(cli),
                "gen",
                str(EXAMPLE / "td.json"),
                "-I",
                os.path.relpath(EXAMPLE / "interfaces", cwd),
                "-o",
                str(out),
                "--partial",
            ],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert proc.returncode == 0, proc.stderr
        digests.append(_tree_digest(out))
    assert all(d == digests[0] for d in digests[1:])
    # nothing machine-specific leaks into the output
    for path in (tmp_path / "out0").rglob("*"):
        if path.is_file():
            text = path.read_bytes()
            assert str(tmp_path).encode() not in text and str(REPO).encode() not in text, path
