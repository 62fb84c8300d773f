"""pytest fixtures for the real-runtime ROS 2 tests; a test module loads them with
`pytest_plugins = ["tests.ros2.fixtures"]` (and imports helpers from tests.ros2.common, never from here).

Nothing here mocks ROS: the RB-1 interfaces are built with CMake (once per definitions hash, tests.ros2.build),
the generated adaptor is built with colcon, the simulated robot runs in its own process. Isolation: the whole
session gets a private ROS_DOMAIN_ID and localhost-only discovery (tests.ros2.env) before rclpy starts.
"""

from __future__ import annotations

import importlib
import json
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tests.ros2 import env
from tests.ros2.build import build_interfaces, colcon_build
from tests.ros2.common import (
    EXAMPLE,
    PACKAGE,
    SIM_DURATION,
    SIM_NAMESPACES,
    Process,
    generate_rclpy,
    require_ros2,
    std_td,
)


@pytest.fixture(scope="session")
def ros2_domain() -> int:
    """Private ROS_DOMAIN_ID and localhost discovery for this worker and its children (before rclpy.init)."""
    require_ros2()
    return env.isolate()


@pytest.fixture(scope="session")
def rb1_prefix(ros2_domain: int) -> Path:
    """The RB-1 interfaces, built with CMake (cached), usable in this process."""
    prefix = build_interfaces()
    env.load_prefix(prefix)
    return prefix


@pytest.fixture(scope="session")
def adaptor_build(rb1_prefix: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The RB-1 rclpy adaptor generated and built with `colcon build`: (package source, install prefix)."""
    base = tmp_path_factory.mktemp("rclpy-ws")
    src = generate_rclpy(EXAMPLE / "td.json", base / "src")
    started = time.monotonic()
    install = colcon_build(base, [rb1_prefix], cmake=False)
    print(f"colcon build of {src.name}: {time.monotonic() - started:.1f} s")
    return src, install


@pytest.fixture(scope="session")
def adaptor(adaptor_build: tuple[Path, Path]) -> ModuleType:
    """The colcon-installed adaptor package, imported."""
    site = str(env.site_packages(adaptor_build[1]))
    if site not in sys.path:
        sys.path.insert(0, site)
    module = importlib.import_module(PACKAGE)
    assert Path(module.__file__ or "").is_relative_to(adaptor_build[1]), module.__file__
    return module


@pytest.fixture(scope="session")
def sim(rb1_prefix: Path) -> Iterator[Process]:
    """The simulated RB-1 (examples/robotnik_rb1/sim/ros2.py), one process serving several robots."""
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", str(SIM_DURATION)]
    for ns in SIM_NAMESPACES:
        args += ["--namespace", ns]
    process = Process(args, env.child_env([rb1_prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        yield process
    finally:
        process.stop()


def server_process(mode: str, namespace: str, prefixes: list[Path]) -> Iterator[Process]:
    """A tests.ros2.blocking_server process (`mode`, robot `namespace`), once its services exist."""
    process = Process([sys.executable, "-m", "tests.ros2.blocking_server", mode, namespace], env.child_env(prefixes))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        yield process
    finally:
        process.stop()


@pytest.fixture
def silent_robot(rb1_prefix: Path) -> Iterator[Process]:
    """A server that takes the gotoQuery request of robot `silent_robot` and never answers."""
    yield from server_process("silent", "silent_robot", [rb1_prefix])


@pytest.fixture
def late_robot(rb1_prefix: Path) -> Iterator[Process]:
    """A gotoQuery server of robot `late_robot` that answers its first request late, the others at once."""
    yield from server_process("late", "late_robot", [rb1_prefix])


@pytest.fixture
def std_server(ros2_domain: int) -> Iterator[Process]:
    """std_srvs Trigger (answers failure) and SetBool (answers success) servers of robot `std_robot`."""
    yield from server_process("std", "std_robot", [])


@pytest.fixture(scope="session")
def std_adaptor(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    """The adaptor of tests.ros2.common.std_td (standard interfaces only), imported from its source."""
    path = tmp_path_factory.mktemp("std") / "td.json"
    path.write_text(json.dumps(std_td(sensors=False)), encoding="utf-8")
    src = generate_rclpy(path, path.parent / "src")
    sys.path.insert(0, str(src))
    return importlib.import_module(src.name)


@pytest.fixture(scope="session")
def ros_node(ros2_domain: int, adaptor: ModuleType) -> Iterator[Any]:
    """One node per test worker, spun in the background by the adaptor's own helper.

    One node (one DDS participant) for the whole session: discovering a new participant sometimes waits for
    Fast DDS's next periodic announcement (about 2.5 s), so a fresh context per test would cost seconds each.
    The tests that need a context of their own make one.
    """
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("adaptor_test", context=context)
    spinner = adaptor.spin_in_background(node)
    try:
        yield node
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)
