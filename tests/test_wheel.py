"""The wheel carries schemas/ and templates/: build it, install it outside the repo, validate there."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

from .conftest import EXAMPLE, REPO


def test_wheel_installs_and_validates_outside_the_repo(tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(dist), str(REPO)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (wheel,) = dist.glob("td2adaptor-*.whl")
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    target = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    # the wheel itself, unpacked by pip from this (test) environment into the fresh one, without deps
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--no-compile", "--target", target, str(wheel)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    # dependencies come from this environment, appended after the fresh site-packages
    Path(target, "zz_deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    work = tmp_path / "elsewhere"
    shutil.copytree(EXAMPLE, work / "rb1", ignore=shutil.ignore_patterns("sim"))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",)}
    proc = subprocess.run(
        [str(py), "-m", "td2adaptor", "validate", "rb1/td.json", "-I", "rb1/interfaces", "--format", "json"],
        cwd=work,
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert '"valid": true' in proc.stdout
    where = subprocess.run(
        [
            str(py),
            "-c",
            "import td2adaptor.resources as r; print(r.data_dir('schemas')); print(r.data_dir('templates'))",
        ],
        cwd=work,
        capture_output=True,
        text=True,
        env=env,
        check=True,
    ).stdout.split()
    assert all(Path(p).is_relative_to(Path(target)) for p in where), where
    assert (Path(where[0]) / "td-1.1.schema.json").is_file()
    assert (Path(target) / "td2adaptor" / "rostypes" / "interfaces" / "std_srvs" / "srv" / "Trigger.srv").is_file()
