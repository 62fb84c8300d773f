"""The pre-commit hook, for real: pre-commit installs td2adaptor from this repository into its own venv.

Edit a TD and commit → the hook regenerates and the commit fails; commit again (with the regenerated files)
→ it passes.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import EXAMPLE, REPO


def _git(cwd: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    env = {
        **os.environ,
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@example.org",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@example.org",
    }
    return subprocess.run(["git", *args], cwd=cwd, check=check, capture_output=True, text=True, env=env, timeout=900)


@pytest.fixture(scope="module")
def hook_repo(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A snapshot of the working tree as a git repository (so uncommitted work is what gets tested)."""
    src = tmp_path_factory.mktemp("hookrepo") / "td2adaptor"
    ignore = shutil.ignore_patterns(
        ".git",
        ".venv",
        ".cache",
        "__pycache__",
        "*.pyc",
        ".pytest_cache",
        ".mypy_cache",
        ".ruff_cache",
        ".hypothesis",
        "generated",
        "dist",
        "build",
    )
    shutil.copytree(REPO, src, ignore=ignore)
    _git(src, "init", "-q")
    _git(src, "add", "-A")
    _git(src, "commit", "-qm", "snapshot")
    return src, _git(src, "rev-parse", "HEAD").stdout.strip()


@pytest.fixture(scope="module")
def pc_home(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """pre-commit's home, shared by the tests: the hook environment is installed once."""
    return tmp_path_factory.mktemp("pc-home")


def _project(work: Path, hook_repo: tuple[Path, str], hook: str, target: str) -> Path:
    """A project with the RB-1's TD and interfaces, a [tool.td2adaptor] target (`target`: its other lines) and
    a pre-commit configuration using `hook` of the snapshot repository."""
    repo, rev = hook_repo
    (work / "rb1").mkdir(parents=True)
    shutil.copy(EXAMPLE / "td.json", work / "rb1" / "td.json")
    shutil.copytree(EXAMPLE / "interfaces", work / "rb1" / "interfaces")
    (work / "pyproject.toml").write_text(
        '[tool.td2adaptor]\noutput = "adaptors"\n\n[[tool.td2adaptor.target]]\ntds = ["rb1/td.json"]\n'
        f'interfaces = ["rb1/interfaces"]\n{target}\n'
    )
    (work / ".pre-commit-config.yaml").write_text(
        f"repos:\n  - repo: {repo}\n    rev: {rev}\n    hooks:\n      - id: {hook}\n"
    )
    return work


def test_hook_regenerates_and_fails_then_passes(hook_repo: tuple[Path, str], pc_home: Path, tmp_path: Path) -> None:
    work = _project(tmp_path / "robots", hook_repo, "td2adaptor-gen", 'backends = ["all"]\npartial = true')
    env = {**os.environ, "PRE_COMMIT_HOME": str(pc_home), "TD2ADAPTOR_NO_CACHE": "1"}
    pre_commit = [sys.executable, "-m", "pre_commit"]
    _git(work, "init", "-q")
    subprocess.run([*pre_commit, "install"], cwd=work, check=True, env=env, capture_output=True, timeout=120)

    def commit(message: str) -> subprocess.CompletedProcess[str]:
        _git(work, "add", "-A")
        return subprocess.run(
            ["git", "commit", "-m", message],
            cwd=work,
            env={
                **env,
                "GIT_AUTHOR_NAME": "t",
                "GIT_AUTHOR_EMAIL": "t@example.org",
                "GIT_COMMITTER_NAME": "t",
                "GIT_COMMITTER_EMAIL": "t@example.org",
            },
            capture_output=True,
            text=True,
            timeout=900,
        )

    first = commit("add robot")
    assert first.returncode != 0, first.stdout + first.stderr
    assert "generated files changed" in first.stdout + first.stderr
    assert (work / "adaptors").is_dir()
    second = commit("add robot with adaptors")
    assert second.returncode == 0, second.stdout + second.stderr
    # editing the TD: the hook regenerates, fails, then passes
    td = (work / "rb1" / "td.json").read_text().replace("Drive to a goal pose", "Drive to the goal pose")
    (work / "rb1" / "td.json").write_text(td)
    third = commit("reword")
    assert third.returncode != 0
    assert "generated files changed" in third.stdout + third.stderr
    fourth = commit("reword with adaptors")
    assert fourth.returncode == 0, fourth.stdout + fourth.stderr
    assert _git(work, "status", "--porcelain").stdout == ""


def test_check_hook_fails_on_stale_adaptors_and_never_writes(
    hook_repo: tuple[Path, str], pc_home: Path, tmp_path: Path
) -> None:
    """`td2adaptor-check`: the commit fails while the committed adaptors are stale; nothing is written."""
    work = _project(tmp_path / "robots", hook_repo, "td2adaptor-check", 'backends = ["events"]')
    env = {
        **os.environ,
        "PRE_COMMIT_HOME": str(pc_home),
        "GIT_AUTHOR_NAME": "t",
        "GIT_AUTHOR_EMAIL": "t@example.org",
        "GIT_COMMITTER_NAME": "t",
        "GIT_COMMITTER_EMAIL": "t@example.org",
    }
    _git(work, "init", "-q")
    subprocess.run([sys.executable, "-m", "pre_commit", "install"], cwd=work, check=True, env=env, timeout=120)

    def commit(message: str) -> subprocess.CompletedProcess[str]:
        _git(work, "add", "-A")
        return subprocess.run(
            ["git", "commit", "-m", message], cwd=work, env=env, capture_output=True, text=True, timeout=900
        )

    first = commit("add robot, no adaptors")
    assert first.returncode != 0 and "generated code is stale" in first.stdout + first.stderr
    assert not (work / "adaptors").exists()  # check never writes
    gen = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "gen"], cwd=work, env=env, capture_output=True, text=True, timeout=300
    )
    assert gen.returncode == 0, gen.stderr
    second = commit("add robot with adaptors")
    assert second.returncode == 0, second.stdout + second.stderr
