"""`td2adaptor run` itself, on real ROS 2 Jazzy (PyPI wheels) and a real mosquitto (issue 30, item 9): a
broker restarted with anonymous access while the node runs ends the node with one clear line and exit 1,
and leaves the robot `offline` there. (The engine-level test is in test_mqtt_guards.py.)"""

from __future__ import annotations

import json
from pathlib import Path

from tests.ros2 import env
from tests.ros2.common import EXAMPLE
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

ROBOT = "check_ros2"
PASSWORD = "never-printed-s3cret"


def test_run_exits_when_its_broker_comes_back_open_to_anonymous_clients(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, tmp_path: Path
) -> None:
    broker = Mosquitto(tmp_path / "broker", users={ROBOT: PASSWORD, "app": "app-pass"})
    broker.start()
    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    td["securityDefinitions"], td["security"] = {"basic_sc": {"scheme": "basic"}}, ["basic_sc"]
    (tmp_path / "td.json").write_text(json.dumps(td), encoding="utf-8")
    environ = env.child_env([rb1_prefix, adaptor_build[1]])
    environ |= {"TD2ADAPTOR_MQTT_USERNAME": ROBOT, "TD2ADAPTOR_MQTT_PASSWORD": PASSWORD}
    environ["TD2ADAPTOR_STATE_DIR"] = str(tmp_path / "state")
    args = [str(tmp_path / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--robot", ROBOT, "--bus", broker.url]
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/status"], username="app", password="app-pass")
    run = RunProcess([*args, "--property-period", "0"], env=environ)
    try:
        run.wait_ready()
        app.wait(lambda ev: [e["payload"]["state"] for _, e in ev][-1:] == ["online"], timeout=20)
        app.close()
        broker.conf.write_text(broker.conf.read_text().replace("allow_anonymous false", "allow_anonymous true"))
        broker.restart()
        assert run.proc.wait(30) == 1, run.output()
        last = run.output().strip().splitlines()[-1]
        assert last.startswith(f"td2adaptor run: robot {ROBOT}: stopped serving: after reconnecting, the MQTT "), last
        assert "accepts clients without credentials" in last and "--allow-anonymous-broker" in last
        assert "td2adaptor run: stopped" in run.output() and PASSWORD not in run.output()
        anonymous = AppClient(broker, [f"td2adaptor/{ROBOT}/status"])  # it gets in: the robot is offline there
        anonymous.wait(lambda ev: [e["payload"]["state"] for _, e in ev][-1:] == ["offline"])
        anonymous.close()
    finally:
        run.close()
        broker.stop()
