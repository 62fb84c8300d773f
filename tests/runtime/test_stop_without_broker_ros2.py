"""SIGTERM stops `td2adaptor run` promptly when its broker is gone (found running the warehouse demo from the
dashboard's tests: after the broker had stopped, the demo's edge nodes were still there 15 s after their
SIGTERM and had to be killed). Whoever stops a fleet (systemd, a supervisor, Ctrl-C) waits for it; with the broker
unreachable nothing the node would publish on the way out (the TD cleared, `offline`) can be acknowledged, so the
node must not wait for acknowledgements, nor for a reconnection, robot by robot.

Real parts: the edge node in a process of its own serving three simulated RB-1s (ROS 2 Jazzy), a real mosquitto
that is stopped under it.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.ros2 import env
from tests.ros2.common import EXAMPLE, PACKAGE, Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, until
from tests.runtime.test_fleet_changes_ros2 import sim_process

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

#: the namespaces of this module's simulated robots (no other ROS 2 test uses them)
NAMESPACES = ("stop_a", "stop_b", "stop_c")
#: the most a stop may take once the broker is gone: the ROS side's shutdown and no wait for the bus (it took
#: 5 s per robot before: each waited for acknowledgements of its offline status that could not come)
STOP_WITHIN = 4.0


@pytest.fixture(scope="module")
def robots(rb1_prefix: Path) -> Iterator[Process]:
    process = sim_process(rb1_prefix, NAMESPACES)
    yield process
    process.stop()


def test_sigterm_stops_a_fleet_promptly_when_the_broker_is_gone(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.yaml"
    lines = [f"bus: {broker.url}", "poll_period: 0.1", "property_period: 0", 'state_dir: ""', "robots:"]
    lines += [f"  - {{robot: {ns}, namespace: {ns}}}" for ns in NAMESPACES]
    fleet.write_text("\n".join(lines) + "\n", encoding="utf-8")
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--package", PACKAGE]
    run = RunProcess([*args, "--config", str(fleet)], env=env.child_env([rb1_prefix, adaptor_build[1]]))
    app = AppClient(broker.url, ["td2adaptor/+/status"], client_id="stop-watch")
    try:
        run.wait_ready()

        def online() -> set[str]:
            return {t.split("/")[1] for t, e in app.events if e.get("payload", {}).get("state") == "online"}

        assert until(lambda: online() == set(NAMESPACES), 30), (online(), run.output())
        app.close()
        broker.stop()
        time.sleep(0.5)  # the node has seen its connections drop
        started = time.monotonic()
        code = run.terminate(signal.SIGTERM, timeout=60)
        took = time.monotonic() - started
    finally:
        if run.proc.poll() is None:
            run.terminate(signal.SIGKILL)
    print(f"SIGTERM -> exit: {took:.2f} s")
    assert code == 0, run.output()
    assert took <= STOP_WITHIN, f"stopped {took:.1f} s after SIGTERM\n{run.output()[-3000:]}"
    assert "Traceback" not in run.output()
