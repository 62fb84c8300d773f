"""`.ci/apt.sh`, the apt-get of every setup script: it waits while another package manager holds the dpkg lock
or the package lists' lock, instead of failing at once (`Could not get lock ...`, which ended `.ci/setup.sh`).

Real apt-get and real locks, on a private copy of apt's state (status file, lists, cache, no sources; apt.conf
through APT_CONFIG), so the machine's own apt is never blocked and no root is needed.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

import pytest

from tests.conftest import REPO

CI = REPO / ".ci"
STATUS = Path("/var/lib/dpkg/status")
#: holds an fcntl lock (apt's kind) on argv[1] until its stdin closes
_HOLDER = """
import fcntl, sys
fh = open(sys.argv[1], "w")
fcntl.lockf(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
print("held", flush=True)
sys.stdin.read()
"""


@pytest.fixture
def apt_state(tmp_path: Path) -> dict[str, str]:
    """The environment of an apt-get working on a private state under tmp_path."""
    if shutil.which("apt-get") is None or not STATUS.is_file():
        pytest.skip("no apt-get/dpkg here: .ci/apt.sh is for Debian and Ubuntu")
    for folder in ("dpkg", "lists/partial", "sources.d", "cache/archives/partial"):
        (tmp_path / folder).mkdir(parents=True)
    shutil.copy(STATUS, tmp_path / "dpkg" / "status")
    conf = tmp_path / "apt.conf"
    conf.write_text(
        f'Dir::State::status "{tmp_path}/dpkg/status";\n'
        f'Dir::State::Lists "{tmp_path}/lists";\n'
        'Dir::Etc::sourcelist "/dev/null";\n'
        f'Dir::Etc::sourceparts "{tmp_path}/sources.d";\n'
        f'Dir::Cache "{tmp_path}/cache";\n',
        encoding="utf-8",
    )
    return {"APT_CONFIG": str(conf), "SUDO": "", "PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "LC_ALL": "C"}


@contextmanager
def _held(lock: Path) -> Iterator[None]:
    """Another process holds `lock` (fcntl, as apt does) inside the block, and lets it go at its end."""
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLDER, str(lock)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert holder.stdin is not None and holder.stdout is not None
    try:
        assert holder.stdout.readline() == "held\n"
        yield
    finally:
        holder.stdin.close()  # the other apt is done
        holder.wait(timeout=30)
        holder.stdout.close()


def _apt(env: dict[str, str], command: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        ["bash", "-c", f'set -euo pipefail; . "{CI}/apt.sh"; {command}'],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _read_until(stream: IO[str], text: str) -> str:
    """Lines of `stream` up to the one containing `text` (EOF first fails the test)."""
    seen = ""
    for line in stream:
        seen += line
        if text in line:
            return seen
    pytest.fail(f"{text!r} never came; got:\n{seen}")


@pytest.mark.parametrize(
    ("lock", "command"),
    [
        ("dpkg/lock-frontend", "apt_get install -y -qq --no-install-recommends dpkg"),  # installed: nothing to do
        ("lists/lock", "apt_get update -qq"),  # the lists lock, which DPkg::Lock::Timeout does not cover
    ],
)
def test_apt_waits_for_a_lock_another_apt_holds(apt_state: dict[str, str], lock: str, command: str) -> None:
    base = Path(apt_state["APT_CONFIG"]).parent
    with _held(base / lock):
        apt = _apt(apt_state, command)
        assert apt.stderr is not None
        said = _read_until(apt.stderr, "waiting for it")
        assert f"another package manager holds a lock (Could not get lock {base / lock}" in said
        assert apt.poll() is None  # still waiting while the lock is held
    out, err = apt.communicate(timeout=60)
    assert apt.returncode == 0, out + err
    assert "Could not get lock" not in out


def test_apt_gives_up_after_the_limit(apt_state: dict[str, str]) -> None:
    base = Path(apt_state["APT_CONFIG"]).parent
    with _held(base / "lists" / "lock"):
        started = time.monotonic()
        apt = _apt({**apt_state, "TD2ADAPTOR_APT_LOCK_TIMEOUT": "2"}, "apt_get update -qq")
        out, err = apt.communicate(timeout=60)
    assert apt.returncode != 0 and time.monotonic() - started >= 2
    assert "Could not get lock" in out and "waiting for it, at most 2 s" in err


def test_every_setup_script_runs_apt_get_through_apt_sh() -> None:
    """A script calling apt-get itself would fail again on another apt's lock."""
    direct = [
        f"{path.name}:{number}: {line.strip()}"
        for path in sorted(CI.glob("*.sh"))
        if path.name != "apt.sh"
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if re.search(r"\bapt-get\s+(?!>)(?!/)", line) and "command -v apt-get" not in line and "no apt-get" not in line
    ]
    assert direct == []
    callers = [p.name for p in CI.glob("*.sh") if "apt_install" in p.read_text(encoding="utf-8") and p.name != "apt.sh"]
    for name in callers:
        assert "apt.sh" in (CI / name).read_text(encoding="utf-8"), f"{name} uses apt_install without sourcing apt.sh"
