"""`td2adaptor scaffold ros1` on real ROS 1 (Debian's rosmaster and rospy): the simulated RB-1 scaffolds to
the example's affordances, read over the master's XML-RPC API and the services' TCPROS headers; the
scaffolded TD, untouched, is generated (rospy) and served by `td2adaptor run --ros 1` (its rospy bridge),
and a mission goes end to end over a real mosquitto.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import td2adaptor
from tests.conftest import REPO
from tests.ros1 import harness
from tests.ros1.harness import Master, Sim
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, check_mission, until
from tests.runtime.rb1 import GOAL, terminal
from tests.scaffold.common import INTERFACES, compare_with_example, compiled_errors, example_td, scaffold, w3c_errors

ROBOT = "scaf_ros1"


@pytest.fixture(scope="module")
def sim(master: Master) -> Iterator[Sim]:
    # a pick long enough for a poll to see it running on a loaded machine
    with harness.run_sim(master, harness.interfaces_dir(), ROBOT, "--duration", "2.0") as s:
        yield s


@pytest.fixture(scope="module")
def scaffolded(master: Master, sim: Sim, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scaffold-ros1") / "td.json"
    done = scaffold(["ros1", "--master-uri", master.uri, "-I", str(INTERFACES), "--title", "Scaffolded RB-1"], out)
    assert done.code == 0, done.stderr
    return out


def test_the_simulated_rb1_on_ros1_scaffolds_to_the_example_td(scaffolded: Path, tmp_path: Path) -> None:
    import json

    doc = json.loads(scaffolded.read_text(encoding="utf-8"))
    compare_with_example(doc, example_td(), "ros1")
    # the master's own /rosout and every node's logger services are left out
    names = [a["forms"][0]["rosv:name"] for s in ("properties", "actions") for a in doc[s].values()]
    assert not [n for n in names if "rosout" in n or "logger" in n]
    assert compiled_errors(doc, tmp_path) == []
    assert w3c_errors(doc) == []


def test_the_scaffolded_td_runs_on_ros1_and_a_mission_goes_end_to_end(
    master: Master, sim: Sim, scaffolded: Path, tmp_path: Path
) -> None:
    gen = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "gen", str(scaffolded), "-I", str(INTERFACES), "-b", "rospy",
         "-o", str(tmp_path / "gen")],
        cwd=REPO, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert gen.returncode == 0, gen.stderr
    result = td2adaptor.compile(scaffolded, interfaces=[INTERFACES])
    assert result.model is not None
    package_src = tmp_path / "gen" / "rospy" / result.model.package_name / "src"
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"], client_id="scaffold-ros1-app")
    environ = {**os.environ, "ROS_HOME": str(master.home), "ROS_IP": "127.0.0.1", "ROS_HOSTNAME": "127.0.0.1"}
    args = [str(scaffolded), "-I", str(INTERFACES), "--ros", "1", "--robot", ROBOT, "--bus", broker.url,
            "--master-uri", master.uri, "--ros1-python", harness.SYSTEM_PYTHON,
            "--package-path", str(package_src), "--package-path", str(harness.interfaces_dir()),
            "--poll-period", "0.05", "--property-period", "0"]  # fmt: skip
    run = RunProcess(args, env=environ)
    try:
        run.wait_ready()
        app.send(f"td2adaptor/{ROBOT}/PickComponent/pickRun", {"correlation": "r1", "payload": {
            "procedure": {"pick_frame_id": "scaf_ros1_cart2"}}})  # fmt: skip
        app.wait(terminal("feedback", "r1"), timeout=30)
        check_mission(app.events, "r1", ["queued", "running", "finished"])
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "r2", "payload": GOAL})
        app.wait(terminal("feedback", "r2"), timeout=30)
        check_mission(app.events, "r2", ["queued", "running", "finished"])
        # the door: the scaffolded write-only property reaches the robot. Not latched on ROS 1 (the master
        # cannot tell), so a command written before the publisher's connection is up may be lost: resend
        assert until(lambda: _door(app, sim), 20.0, 0.0)
    finally:
        run.close()
        app.close()
        broker.stop()


def _door(app: AppClient, sim: Sim) -> bool:
    app.send(f"td2adaptor/{ROBOT}/CommandComponent/command/write", {"payload": {"data": 0.75}})
    try:
        sim.read_until("door 0.75", 1.0)
    except AssertionError:
        return False
    return True


def test_a_service_whose_server_is_gone_is_left_out_with_a_warning(master: Master, sim: Sim, tmp_path: Path) -> None:
    import xmlrpc.client

    from tests.ports import free_port

    # registered at the master by a node that then died: its rosrpc port answers nobody
    gone = f"rosrpc://127.0.0.1:{free_port()}"
    with xmlrpc.client.ServerProxy(master.uri) as proxy:
        code, _, _ = proxy.registerService("/ghost_node", f"/{ROBOT}/ghost", gone, f"http://127.0.0.1:{free_port()}/")
        assert code == 1
    try:
        done = scaffold(
            ["ros1", "--master-uri", master.uri, "-I", str(INTERFACES), "--wait", "3"], tmp_path / "td.json"
        )
        assert done.code == 0, done.stderr
        assert "SCF107" in done.stderr and f"/{ROBOT}/ghost" in done.stderr
        assert done.doc is not None and len(done.doc["actions"]) == 9
    finally:
        with xmlrpc.client.ServerProxy(master.uri) as proxy:
            proxy.unregisterService("/ghost_node", f"/{ROBOT}/ghost", gone)


def test_actionlib_servers_scaffold_to_td_actions(master: Master, tmp_path: Path) -> None:
    """Real actionlib servers (tests/ros1/fibonacci_server.py: burst, fibonacci, hasty, picky, stuck, tardy) show as
    five topics each on the master; the scaffold folds them into ROS 1 actions."""
    actions = REPO / "tests" / "data" / "actions"
    modules = tmp_path / "genpy"
    built = subprocess.run(
        [harness.SYSTEM_PYTHON, str(harness.HERE / "build_actions.py"), str(actions), str(modules)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert built.returncode == 0, built.stderr
    with harness.run_server(master, modules, "fibonacci_server.py", "scaf_fibo1", "0.01"):
        args = ["ros1", "--master-uri", master.uri, "-I", str(actions), "--namespace", "/scaf_fibo1"]
        done = scaffold(args, tmp_path / "td.json")
    assert done.code == 0, done.stderr
    doc = done.doc
    assert doc is not None and "properties" not in doc, doc  # no goal/cancel/status/feedback/result topics
    assert sorted(doc["actions"]) == ["burst", "fibonacci", "hasty", "picky", "stuck", "tardy"]
    for name, action in doc["actions"].items():
        form = action["forms"][0]
        assert form["rosv:name"] == f"/{{{{robotName}}}}/{name}" and form["rosv:interface"] == "action"
        assert form["rosv:type"] == "test_msgs/action/Fibonacci"
        assert set(action["input"]["properties"]) == {"order"}
        assert set(action["output"]["properties"]) == {"sequence"}
    assert compiled_errors(doc, tmp_path, [actions]) == []
    assert w3c_errors(doc) == []
