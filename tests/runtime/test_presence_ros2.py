"""Presence, ownership, `fleet status` and metrics of a real `td2adaptor run` on ROS 2 Jazzy (issue 32): the
simulated RB-1 in its own process is stopped and started again under the edge node, a second edge node for the
same robot is refused, the edge node is killed -9. Real mosquitto, real rclpy in the session's private domain."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tests.ports import free_port
from tests.ros2 import env
from tests.ros2.common import EXAMPLE, PACKAGE, Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, until
from tests.runtime.rb1 import GOAL, terminal

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build, ...

ROBOT = "pres_ros2"  # also its namespace: no other test's simulation serves it


def simulation(prefix: Path) -> Process:
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "0.5", "--namespace", ROBOT]
    process = Process(args, env.child_env([prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
    except BaseException:
        process.stop()
        raise
    return process


def status_of(app: AppClient, robot: str = ROBOT) -> Callable[[], dict[str, Any]]:
    """The last status `app` received of `robot`."""

    def last() -> dict[str, Any]:
        with app.cond:
            found = [e["payload"] for t, e in app.events if t == f"td2adaptor/{robot}/status" and "payload" in e]
        return found[-1] if found else {}

    return last


def test_presence_ownership_fleet_status_and_metrics_of_a_ros2_edge_node(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, broker: Mosquitto, tmp_path: Path
) -> None:
    environ = env.child_env([rb1_prefix, adaptor_build[1]])
    environ["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), environ["PATH"]])
    environ.update(TD2ADAPTOR_PRESENCE_PERIOD="0.2", TD2ADAPTOR_STATE_DIR=str(tmp_path / "state"))
    entry_point = [str(adaptor_build[1] / "lib" / PACKAGE / "edge_node")]
    metrics = f"127.0.0.1:{free_port()}"
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--robot", ROBOT, "--bus", broker.url]
    args += ["--call-timeout", "10", "--property-period", "0", "--poll-period", "0.1"]
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
    status = status_of(app)
    sim = simulation(rb1_prefix)
    run = RunProcess([*args, "--metrics", metrics], env=environ, command=entry_point)
    second: RunProcess | None = None
    try:
        run.wait_ready()
        assert until(lambda: status().get("robot") == "present", 30.0), status()
        owner = status()["owner"]
        assert (status()["state"], owner["pid"]) == ("online", run.proc.pid)

        # the metrics, scraped over HTTP
        with urllib.request.urlopen(f"http://{metrics}/metrics", timeout=10) as answer:
            text = answer.read().decode()
        assert "td2adaptor_robots_owned 1.0" in text
        assert f'td2adaptor_robot_present{{robot="{ROBOT}"}} 1.0' in text

        # a second edge node for the same robot stops at once, saying why; the first goes on
        second = RunProcess(args, env=environ, command=entry_point)
        assert second.proc.wait(60) == 1, second.output()
        assert f"robot {ROBOT} is already served by process {run.proc.pid} on " in second.output()
        assert "Traceback" not in second.output()
        assert run.proc.poll() is None and status()["owner"] == owner and status()["state"] == "online"
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "first", "payload": GOAL})
        app.wait(terminal("feedback", "first"), timeout=30)

        # the operator's view
        view = subprocess.run(
            [sys.executable, "-m", "td2adaptor", "fleet", "status", "--bus", broker.url],
            capture_output=True,
            text=True,
            timeout=60,
        )
        (row,) = [line.split() for line in view.stdout.splitlines() if line.startswith(ROBOT + " ")]
        assert row[:4] == [ROBOT, "online", "present", f"{run.proc.pid}@{owner['host']}"], view.stdout

        # the robot's ROS nodes stop: absent within a bound, and an invoke is answered at once
        sim.stop()
        stopped = time.monotonic()
        assert until(lambda: status().get("robot") == "absent", 10.0), status()
        print(f"robot absent in the status {time.monotonic() - stopped:.2f} s after its simulation stopped")
        sent = time.monotonic()
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "gone", "payload": GOAL})
        app.wait(terminal("feedback", "gone"), timeout=15)
        answered = time.monotonic() - sent
        assert answered < 3.0, f"answered after {answered:.1f} s: not at once (call_timeout is 10 s)"
        errors = [e["payload"] for _, e in app.events if e.get("type") == "error" and e.get("correlation") == "gone"]
        assert [e["code"] for e in errors] == ["absent"], errors

        # started again: present
        sim = simulation(rb1_prefix)
        assert until(lambda: status().get("robot") == "present", 30.0), status()

        # the edge node killed -9: the broker's will says offline, naming the process that served it
        run.proc.send_signal(signal.SIGKILL)
        run.proc.wait(10)
        assert until(lambda: status().get("state") == "offline", 10.0), status()
        assert status()["owner"]["pid"] == owner["pid"]
    finally:
        if second is not None:
            second.close()
        run.close()
        sim.stop()
        app.close()
