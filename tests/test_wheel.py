"""The wheel carries its schemas, templates and verbatim files: build it, install it outside the repo, use it there."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

from td2adaptor.backends import registry
from tests.conftest import EXAMPLE, REPO


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
    # every backend generates from the wheel's own templates and verbatim files
    gen = subprocess.run(
        # (the mROS tree stated to take the RB-1 types' TCPROS headers, as pyproject.toml does)
        [str(py), "-m", "td2adaptor", "gen", "rb1/td.json", "-I", "rb1/interfaces", "--partial", "-o", "out"]
        + ["--option", "mros.tcpros_header_max=8192"],
        cwd=work,
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert gen.returncode == 0, gen.stderr
    for backend in registry.builtin():  # every backend the wheel ships (found in the source tree's registry)
        assert (work / "out" / backend).is_dir(), backend
    assert (work / "out" / "events" / "README.md").is_file()  # the index, from the wheel's index.md.j2
    installed = Path(target) / "td2adaptor"
    assert (installed / "frontend" / "schemas" / "td-1.1.schema.json").is_file()
    assert (installed / "rostypes" / "interfaces" / "std_srvs" / "srv" / "Trigger.srv").is_file()
    assert (installed / "py.typed").is_file()
    for page in ("index.html", "app.js", "schemaform.js", "style.css"):  # the dashboard's page: no build step
        assert (installed / "dashboard" / "static" / page).is_file(), page
    # the interface-build helper is part of the wheel and works from it (a folder with no package: one line)
    (work / "empty").mkdir()
    build = subprocess.run(
        [str(py), "-m", "td2adaptor.support.ros2build", "empty", "cache"],
        cwd=work,
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert build.returncode == 1 and build.stderr.startswith("ros2build: no interface package in empty")
    # the demo needs the source checkout, and says so in one line
    demo = subprocess.run(
        [str(py), "-m", "td2adaptor", "demo", "warehouse"], cwd=work, capture_output=True, text=True, env=env
    )
    assert demo.returncode == 1 and "source checkout" in demo.stderr and "Traceback" not in demo.stderr
