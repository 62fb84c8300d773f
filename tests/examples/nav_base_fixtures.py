"""Fixtures for the nav_base example against real ROS 2 Jazzy (loaded with `pytest_plugins`).

Nothing is mocked: nav_base_msgs (the example's own actions) is built with the project's interface build
(td2adaptor.support.ros2build, cached in .cache/ros2-interfaces), the rclpy adaptor is generated from
examples/nav_base/td.json and imported from its source, and the simulated bases run in their own process
(examples/nav_base/sim/ros2.py) with real rclpy action servers.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from td2adaptor.support import ros2build
from tests import generated
from tests.examples.nav_base import BASES, EXAMPLE, FEEDBACK_RATE, INTERFACES, PACKAGE, SPEED
from tests.ros2 import env
from tests.ros2.build import CACHE, COLCON_HOME
from tests.ros2.common import Process


@pytest.fixture(scope="session")
def nav_prefix(ros2_domain: int) -> Path:
    """nav_base_msgs built with CMake (once per definitions hash), usable in this process."""
    prefix = ros2build.build_interfaces(INTERFACES, CACHE, colcon_home=COLCON_HOME)
    env.load_prefix(prefix)
    return prefix


@pytest.fixture(scope="session")
def nav_adaptor(nav_prefix: Path, tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    """The rclpy adaptor of examples/nav_base/td.json, generated and imported from its source."""
    _, package = generated.generate(
        "rclpy", EXAMPLE / "td.json", tmp_path_factory.mktemp("nav-base-rclpy"), interfaces=[INTERFACES]
    )
    assert package.name == PACKAGE
    sys.path.insert(0, str(package))
    return importlib.import_module(PACKAGE)


@pytest.fixture(scope="module")
def nav_sim(nav_prefix: Path) -> Iterator[Process]:
    """The simulated bases BASES, one process."""
    args = [sys.executable, "-m", "examples.nav_base.sim.ros2", "--prefix", str(nav_prefix)]
    args += ["--speed", str(SPEED), "--feedback-rate", str(FEEDBACK_RATE), "--run-for", "600"]
    for ns in BASES:
        args += ["--namespace", ns]
    process = Process(args, env.child_env([nav_prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=60)
        yield process
    finally:
        process.stop()


@pytest.fixture(scope="module")
def nav_node(nav_adaptor: ModuleType) -> Iterator[Any]:
    """A node of this process, spun in the background by the adaptor's own helper."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("nav_base_test", context=context)
    spinner = nav_adaptor.spin_in_background(node)
    try:
        yield node
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)
