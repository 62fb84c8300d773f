"""`python -m td2adaptor.runtime.ros2build` refuses what it cannot build with one line and exit 1, never a
traceback (the build itself is exercised by every ROS 2 test through tests/ros2/build.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from td2adaptor.runtime.ros2build import BuildError, packages_in
from tests.conftest import EXAMPLE


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "td2adaptor.runtime.ros2build", *args], capture_output=True, text=True, timeout=60
    )


@pytest.mark.parametrize("layout", ["empty", "no_package_xml", "missing"])
def test_nothing_to_build_is_one_line(tmp_path: Path, layout: str) -> None:
    src = tmp_path / "interfaces"
    if layout != "missing":
        src.mkdir()
    if layout == "no_package_xml":
        (src / "my_msgs" / "msg").mkdir(parents=True)
        (src / "my_msgs" / "msg" / "Ping.msg").write_text("int32 n\n")
    proc = _run(str(src), str(tmp_path / "cache"))
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert proc.stderr.startswith("ros2build: ") and str(src) in proc.stderr
    assert not (tmp_path / "cache").exists()


def test_usage() -> None:
    proc = _run()
    assert proc.returncode == 2 and "usage:" in proc.stderr


def test_a_folder_of_packages_or_one_package() -> None:
    folder = EXAMPLE / "interfaces"
    assert [p.name for p in packages_in(folder)] == sorted(p.parent.name for p in folder.glob("*/package.xml"))
    assert packages_in(folder / "procedures_msgs") == [folder / "procedures_msgs"]
    with pytest.raises(BuildError):
        packages_in(folder / "procedures_msgs" / "msg")
