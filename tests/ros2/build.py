"""Build ROS 2 packages for the tests: `td2adaptor.support.ros2build` with the repository's paths as defaults.

The build code lives in the package (the warehouse demo needs it too); this module keeps the names the tests
and benchmarks import, with the RB-1 interfaces and the repository's `.cache/` as defaults.

    .venv/bin/python -m tests.ros2.build      # build (or find) the RB-1 interfaces, print the prefix
"""

from __future__ import annotations

from pathlib import Path

from td2adaptor.support import ros2build
from td2adaptor.support.ros2build import (
    definitions_hash,
    file_lock,
    fix_cmake_exports,
    prepare_sources,
    referenced_packages,
    translate,
    translate_line,
)
from tests.ros2.env import PY_DIR, REPO, VENV

INTERFACES = REPO / "examples" / "robotnik_rb1" / "interfaces"
CACHE = REPO / ".cache" / "ros2-interfaces"
COLCON_HOME = REPO / ".cache" / "colcon-home"

__all__ = [
    "CACHE",
    "INTERFACES",
    "PY_DIR",
    "REPO",
    "VENV",
    "build_env",
    "build_interfaces",
    "colcon_build",
    "definitions_hash",
    "file_lock",
    "fix_cmake_exports",
    "prepare_sources",
    "referenced_packages",
    "translate",
    "translate_line",
]


def build_env(prefixes: list[Path]) -> dict[str, str]:
    """Environment for CMake/colcon (see td2adaptor.support.ros2build.build_env)."""
    return ros2build.build_env(prefixes, COLCON_HOME)


def colcon_build(base: Path, prefixes: list[Path], *, cmake: bool) -> Path:
    """`colcon build --merge-install` of every package under `base/src`; the install prefix."""
    return ros2build.colcon_build(base, prefixes, cmake=cmake, colcon_home=COLCON_HOME)


def build_interfaces(src: Path = INTERFACES, cache: Path = CACHE) -> Path:
    """The install prefix of the RB-1 interfaces, built once per definitions hash."""
    return ros2build.build_interfaces(src, cache, colcon_home=COLCON_HOME)


if __name__ == "__main__":
    print(build_interfaces())
