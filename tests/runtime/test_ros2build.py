"""`python -m td2adaptor.support.ros2build` refuses what it cannot build with one line and exit 1, never a
traceback (the build itself is exercised by every ROS 2 test through tests/ros2/build.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from td2adaptor.support.ros2build import BuildError, packages_in
from tests.conftest import EXAMPLE
from tests.ros2.common import require_ros2


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "td2adaptor.support.ros2build", *args], capture_output=True, text=True, timeout=300
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


def _tiny_package(root: Path) -> Path:
    src = root / "interfaces" / "tiny_msgs"
    (src / "msg").mkdir(parents=True)
    (src / "msg" / "Ping.msg").write_text("int32 n\n")
    (src / "package.xml").write_text(
        '<?xml version="1.0"?>\n<package format="3">\n  <name>tiny_msgs</name>\n  <version>0.0.1</version>\n'
        "  <description>a test interface package</description>\n"
        '  <maintainer email="tests@td2adaptor.invalid">tests</maintainer>\n  <license>Apache-2.0</license>\n'
        "  <buildtool_depend>ament_cmake</buildtool_depend>\n"
        "  <buildtool_depend>rosidl_default_generators</buildtool_depend>\n"
        "  <exec_depend>rosidl_default_runtime</exec_depend>\n"
        "  <member_of_group>rosidl_interface_packages</member_of_group>\n"
        "  <export><build_type>ament_cmake</build_type></export>\n</package>\n"
    )
    return src.parent


def test_a_build_shows_progress_on_a_terminal_and_is_quiet_in_a_log(tmp_path: Path) -> None:
    require_ros2()
    import os
    import pty

    src = _tiny_package(tmp_path)
    leader, follower = pty.openpty()  # stderr on a terminal, as for a user at a shell
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "td2adaptor.support.ros2build", str(src), str(tmp_path / "cache")],
            stdout=subprocess.PIPE,
            stderr=follower,
            text=True,
            timeout=300,
        )
        os.close(follower)
        follower = -1
        shown = os.read(leader, 65536).decode()
    finally:
        if follower >= 0:
            os.close(follower)
        os.close(leader)
    assert proc.returncode == 0, shown
    assert "ros2build: building tiny_msgs with CMake (once; cached in" in shown and "ros2build: built in" in shown
    assert Path(proc.stdout.strip(), "share", "tiny_msgs").is_dir()
    # the same build with stderr not a terminal (a CI log): not a word besides the prefix
    quiet = _run(str(src), str(tmp_path / "cache-ci"))
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr
    assert Path(quiet.stdout.strip(), "share", "tiny_msgs").is_dir()


def test_relative_paths_as_the_readme_writes_them(tmp_path: Path) -> None:
    # `ros2build examples/robotnik_rb1/interfaces .cache/ros2-interfaces`: colcon runs in the build folder, so
    # relative paths once built nothing there, marked the build done and printed a prefix that did not exist
    require_ros2()
    _tiny_package(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "td2adaptor.support.ros2build", "interfaces", "cache"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    prefix = Path(proc.stdout.strip())
    assert prefix.is_absolute() and prefix.is_relative_to(tmp_path / "cache")
    assert (prefix / "share" / "tiny_msgs").is_dir()


def test_an_interface_package_this_environment_lacks_is_named_before_building(tmp_path: Path) -> None:
    """A robot's action using trajectory_msgs (an arm's, say) when the ros2 extra has no such wheel: one line
    naming the package and the wheel, before any CMake run (which used to fail with a page of its output)."""
    require_ros2()
    src = _tiny_package(tmp_path)
    (src / "tiny_msgs" / "action").mkdir()
    (src / "tiny_msgs" / "action" / "Move.action").write_text(
        "trajectory_msgs/JointTrajectory trajectory\nduration tolerance\n---\nint32 error_code\n---\nstring state\n"
    )
    proc = _run(str(src), str(tmp_path / "cache"))
    assert proc.returncode == 1, proc.stdout
    assert proc.stderr == (
        "ros2build: interface packages this environment does not have: tiny_msgs uses trajectory_msgs "
        "(pip install ros-jazzy-trajectory-msgs)\n"
    )
    assert not (tmp_path / "cache").exists()
