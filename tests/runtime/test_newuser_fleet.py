"""What a new user ran into with the fleet features (issue 32), tried with a robot nobody here wrote for (a
conveyor): each test reproduces one finding on real parts (mosquitto, the edge node as `td2adaptor run` on
ROS 2 Jazzy, or its admin listener with simulated robots) and holds the fix.
"""

from __future__ import annotations

import re
import urllib.request
from pathlib import Path

from tests.ros2 import env
from tests.ros2.common import EXAMPLE, generate_rclpy
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import RunProcess

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix


def test_metrics_on_port_0_take_a_free_port_and_the_start_line_names_it(
    rb1_prefix: Path, broker: Mosquitto, tmp_path: Path
) -> None:
    """`--metrics 127.0.0.1:0` was refused with "give HOST:PORT" (which it was); like `dashboard --listen`, port 0
    now takes a free port, and the start line says which."""
    package = generate_rclpy(EXAMPLE / "rb1.tm.json", tmp_path / "src")
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--package-path", str(package)]
    args += ["--prefix", str(rb1_prefix), "--bus", broker.url, "--discover", "--metrics", "127.0.0.1:0"]
    environ = env.child_env([rb1_prefix])
    environ["TD2ADAPTOR_STATE_DIR"] = str(tmp_path / "state")
    run = RunProcess(args, env=environ)
    try:
        run.wait_ready()
        found = re.search(r"metrics on http://127\.0\.0\.1:(\d+)/metrics", run.output())
        assert found is not None and int(found.group(1)) > 0, run.output()
        with urllib.request.urlopen(f"http://127.0.0.1:{found.group(1)}/metrics", timeout=10) as answer:
            text = answer.read().decode()
        assert "td2adaptor_robots_owned 0.0" in text, text
    finally:
        code = run.terminate()
    assert code == 0, run.output()
