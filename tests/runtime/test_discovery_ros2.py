"""`td2adaptor run --directory URL`, the command itself, on real ROS 2 Jazzy (PyPI wheels) with the simulated
RB-1, a real mosquitto and a real TD directory (Domus TDD on Oxigraph, tests/runtime/tdd.py): the robot's TD,
the whole RB-1, is registered once the node is online (read back as RDF: Domus cannot frame a TD that large
as JSON) and removed when the node is stopped with SIGTERM."""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.ros2 import env
from tests.ros2.common import EXAMPLE, Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, until
from tests.runtime.tdd import TddServer

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

NAMESPACE = "disco_ros2"  # this module's own simulated robot
ROBOT = "disco_ros2"
THING = f"urn:dev:wot:robotnik:rb1:{ROBOT}"


@pytest.fixture
def directory(tmp_path: Path) -> Iterator[TddServer]:
    server = TddServer(tmp_path / "tdd")
    server.start()
    yield server
    server.stop()


@pytest.fixture
def robot_sim(rb1_prefix: Path) -> Iterator[Process]:
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "1", "--namespace", NAMESPACE]
    process = Process(args, env.child_env([rb1_prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        yield process
    finally:
        process.stop()


def test_run_registers_the_robot_td_with_the_directory_and_removes_it_on_sigterm(
    adaptor_build: tuple[Path, Path],
    rb1_prefix: Path,
    robot_sim: Process,
    broker: Mosquitto,
    directory: TddServer,
) -> None:
    environ = env.child_env([rb1_prefix, adaptor_build[1]])
    environ["TD2ADAPTOR_DIRECTORY_TOKEN"] = "never-printed-token"  # Domus ignores it; the node must not print it
    args = [str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--robot", ROBOT, "--bus", broker.url]
    args += ["--property-period", "0", "--directory", directory.url, "--directory-ttl", "300", "--log-level", "info"]
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/td"])
    run = RunProcess(args, env=environ)
    try:
        run.wait_ready()
        assert f"TDs registered with {directory.url}" in run.output()
        tds = app.wait(lambda ev: any("id" in e for _, e in ev), timeout=20)
        td = next(e for _, e in tds if "id" in e)
        assert td["id"] == THING
        assert until(lambda: directory.triples(THING) is not None, 60), run.output() + directory.output()
        triples = directory.triples(THING) or ""
        goto = td["actions"]["gotoRun"]["forms"][0]
        assert f'"{goto["href"]}"' in triples or f"<{goto['href']}>" in triples
        assert until(lambda: f"Thing Description {THING} registered with" in run.output(), 10), run.output()
        assert run.terminate(signal.SIGTERM) == 0, run.output()
        assert "Thing Description removed from the directory" in run.output()
        assert directory.triples(THING) is None
        assert "never-printed-token" not in run.output()
    finally:
        run.close()
        app.close()
