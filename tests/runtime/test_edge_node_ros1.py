"""The edge node on real ROS 1 (Debian's rospy and rosmaster, no mocks): the generated rospy package's
`GeneratedPort`s run under /usr/bin/python3 in the ROS 1 bridge (td2adaptor.runtime.ros.bridge) against the
simulated RB-1; a mission goes end to end through the engine and the local bus; `td2adaptor run --ros 1`
serves a robot over a real mosquitto.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import xmlrpc.client
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from td2adaptor.cli.main import cli
from td2adaptor.runtime import LocalBroker, PortCallFailed, PortTimeout, PortUnavailable, RuntimeConfig, loop, serve
from td2adaptor.runtime.engine import context
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.ros.bridge import Ros1Bridge
from td2adaptor.runtime.ros.genport import Layout
from td2adaptor.runtime.ros.port import RosSetupError
from tests import generated
from tests.conftest import EXAMPLE
from tests.ros1 import harness
from tests.ros1.harness import Master, Sim
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import CLASS_NAME, RunProcess, check_mission, feedback, until
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_model, terminal

PKG = "robotnik_rb_1_adaptor"
ROBOT = "edge_ros1"


@pytest.fixture(scope="module")
def package_src(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    """The RB-1 rospy package generated into a temporary directory; its src/ (to import from)."""
    _, package = generated.generate(
        "rospy", EXAMPLE / "td.json", tmp_path_factory.mktemp("rospy"), interfaces=[EXAMPLE / "interfaces"]
    )
    return package / "src"


@pytest.fixture(scope="module")
def interfaces(ros1: None) -> Path:
    return harness.interfaces_dir()


@pytest.fixture(scope="module")
def sim(master: Master, interfaces: Path) -> Iterator[Sim]:
    with harness.run_sim(master, interfaces, ROBOT, "--duration", "0.5") as s:
        yield s


def test_bridge_ports_drive_the_ros1_sim_and_a_mission_runs_through_the_engine(
    master: Master, sim: Sim, interfaces: Path, package_src: Path
) -> None:
    model = rb1_model()
    bridge = rb1_bridge(model, master, interfaces, package_src, restart_period=0.5)
    bridge.start()
    try:
        port = bridge.port(ROBOT)
        started = port.start("PickComponent", "pickRun", {"procedure": {"pick_frame_id": "edge_ros1_cart2"}}, 5.0)
        assert started.mission_id is not None and started.mission_id > 0
        assert started.response["state"]["current_state"] == "queued"
        # ROS 1 times come out as ROS 1 names them (the robot's TD and event schemas say secs/nsecs too)
        assert set(started.response["state"]["header"]["stamp"]) == {"secs", "nsecs"}
        with pytest.raises(PortCallFailed, match="already running a procedure") as busy:
            port.start("PickComponent", "pickRun", {}, 5.0)
        assert busy.value.response is not None and busy.value.response["state"]["current_state"] == "unknown"
        cancelled = port.cancel("PickComponent", "pickCancel", started.mission_id, 5.0)
        assert cancelled["state"]["header"]["id"] == started.mission_id
        assert (cancelled["state"]["last_event"], cancelled["last_message"]["data"]) == ("cancel", "Cancelled")
        with pytest.raises(PortCallFailed, match="no procedure with id 777"):
            port.query("PickComponent", "pickQuery", 777, 5.0)

        # a mission end to end: engine and local bus here, rospy in the bridge
        broker = LocalBroker()
        app = LocalApp(broker)
        config = RuntimeConfig(robot=ROBOT, poll_period=0.05, property_period=0.1, call_timeout=5.0)
        engine = serve(model, port, config, broker=broker, distro="ros1")
        try:
            app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "r1", "payload": GOAL})
            app.wait(terminal("feedback", "r1"), timeout=20)
            fb = check_mission(app.events, "r1", ["queued", "running", "finished"])
            assert fb[-1]["payload"]["message"] == "Perfect"
            app.wait(
                lambda ev: any(
                    t.endswith("/PoseMarkerComponent/poseMarker")
                    and "wot-thing" not in t
                    and [m["id"] for m in e["payload"]["markers"]] == [3]
                    for t, e in ev
                ),
                timeout=10,
            )
            app.send(f"td2adaptor/{ROBOT}/DoorComponent/door/write", {"payload": {"data": 0.5}})
            assert sim.read_until("door 0.5", 10.0)
        finally:
            engine.stop()
        assert check_outbound(app.events, "ros1") > 0  # strict: ROS 1 time names, no unknown keys

        def status() -> Any:
            return port.read_property("AvailabilityComponent", "availability", 5.0)

        # the latest Status may still be one published before the move ended: wait for the new pose
        assert until(lambda: status()["robot_status"]["pose"]["pose"]["x"] == 1.5, 10.0)
        assert status()["robot_id"] == ROBOT
        # the bridge dies: calls fail as unreachable, and the next call after the restart period restarts it
        pid = bridge.pid
        assert pid is not None
        # restarts are rate-limited from the last start: while the period has not passed since then, calls
        # fail; once it has, the next call restarts. Both cases explicitly, whatever the machine's speed.
        bridge.restart_period = 3600.0
        os.kill(pid, signal.SIGKILL)
        assert until(lambda: not _alive(port), 10.0)
        assert not _alive(port) and bridge.starts == 1
        bridge.restart_period = 0.5
        assert until(lambda: _alive(port), 20.0, 0.2)
        assert bridge.pid != pid and bridge.starts == 2
    finally:
        bridge.close()


def test_through_the_bridge_calls_are_answered_on_its_reader_without_the_call_pool(
    master: Master, sim: Sim, interfaces: Path, package_src: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Through the ROS 1 bridge the engine writes a query's, a plain-less procedure's start, polls and cancel
    requests from its loop, and the bridge's reader publishes the answer: no call-pool thread waits for the
    child's reply (one thread hand-off fewer each way, as on ROS 2)."""
    model = rb1_model()
    bridge = rb1_bridge(model, master, interfaces, package_src)
    bridge.start()
    pooled: list[str] = []  # the robot's calls handed to the call pool (its lane)
    submit = loop.Lane.submit

    def counted(lane: loop.Lane, task: Any) -> None:
        pooled.append(threading.current_thread().name)
        submit(lane, task)

    published: list[tuple[str, str]] = []  # (event kind, thread)
    send = Outbox.send

    def recorded(outbox: Outbox, spec: Any, data: bytes, **kw: Any) -> None:
        published.append((spec.kind.value, threading.current_thread().name))
        send(outbox, spec, data, **kw)

    try:
        port = bridge.port(ROBOT)

        assert until(lambda: _answering(port), 20.0, 0.2)
        monkeypatch.setattr(loop.Lane, "submit", counted)
        monkeypatch.setattr(Outbox, "send", recorded)
        broker = LocalBroker()
        app = LocalApp(broker)
        config = RuntimeConfig(robot=ROBOT, poll_period=0.05, property_period=0, call_timeout=5.0)
        engine = serve(model, port, config, broker=broker, distro="ros1")
        root = f"td2adaptor/{ROBOT}"
        try:
            app.send(f"{root}/PickComponent/pickRun", {"correlation": "p", "payload": {"procedure": {}}})
            app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, "p")], timeout=20)
            app.send(f"{root}/PickComponent/pickCancel", {"correlation": "stop"})
            app.wait(terminal("feedback", "p"), timeout=20)
            app.send(f"{root}/GoToComponent/gotoQuery", {"correlation": "q", "mission": 4242})
            app.wait(lambda ev: any(e.get("type") == "state" and e.get("correlation") == "q" for _, e in ev))
        finally:
            engine.stop()
    finally:
        bridge.close()
    state = next(e for _, e in app.events if e.get("type") == "state" and e.get("correlation") == "q")
    assert state["payload"]["message"] == "no procedure with id 4242", state  # the robot's answer, read
    assert pooled == [], f"calls handed to the call pool: {len(pooled)}"
    assert {thread for kind, thread in published if kind in ("feedback", "state")} == {"ros1-bridge-reader"}


def test_a_call_the_stopped_bridge_never_answers_is_answered_once_after_its_guard_and_not_again(
    master: Master, sim: Sim, interfaces: Path, package_src: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A call sent without a waiting thread still ends when its port never answers (here the bridge's child is
    stopped, alive but silent): the engine answers it with an error after the call timeout and its guard's
    margin, and the reply that comes once the child goes on is not answered a second time."""
    monkeypatch.setattr(context, "QUICK_MARGIN", 0.5)
    model = rb1_model()
    bridge = rb1_bridge(model, master, interfaces, package_src)
    bridge.start()
    pid = bridge.pid
    assert pid is not None
    try:
        port = bridge.port(ROBOT)

        assert until(lambda: _answering(port), 20.0, 0.2)
        broker = LocalBroker()
        app = LocalApp(broker)
        config = RuntimeConfig(robot=ROBOT, poll_period=0.05, property_period=0, call_timeout=1.0)
        engine = serve(model, port, config, broker=broker, distro="ros1")
        try:
            os.kill(pid, signal.SIGSTOP)
            begin = time.monotonic()
            app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoQuery", {"correlation": "q", "mission": 4242})
            app.wait(lambda ev: any(e.get("correlation") == "q" and "type" in e for _, e in ev), timeout=20)
            elapsed = time.monotonic() - begin
            os.kill(pid, signal.SIGCONT)
            answers = [e for _, e in app.events if e.get("correlation") == "q" and "type" in e]  # not the query
            assert [e["type"] for e in answers] == ["error"], answers
            assert "gotoQuery of mission 4242 failed" in answers[0]["payload"]["message"], answers
            assert 1.4 <= elapsed < 10.0, elapsed
            assert until(lambda: _answering(port), 20.0, 0.2)  # the child goes on, answers what it was asked
            time.sleep(0.5)
        finally:
            engine.stop()
    finally:
        os.kill(pid, signal.SIGCONT)
        bridge.close()
    assert [e["type"] for _, e in app.events if e.get("correlation") == "q" and "type" in e] == ["error"]


def test_values_no_ros_type_holds_never_reach_the_ros1_robot(
    master: Master, sim: Sim, interfaces: Path, package_src: Path
) -> None:
    """Issue 30 on ROS 1: what no ROS number or text holds is refused before the bridge is asked (envelope and
    WoT topics); the door hears only the valid command after them."""
    model = rb1_model()
    bridge = rb1_bridge(model, master, interfaces, package_src)
    bridge.start()
    broker = LocalBroker()
    app = LocalApp(broker, f"td2adaptor/{ROBOT}/error")
    config = RuntimeConfig(robot=ROBOT, poll_period=0.05, property_period=0, call_timeout=5.0, state_dir="")
    engine = serve(model, bridge.port(ROBOT), config, broker=broker, distro="ros1")
    heard = len(sim.lines)
    try:
        refused = [
            (f"td2adaptor/{ROBOT}/DoorComponent/door/write", b'{"payload":{"data":1e400}}', "/payload/data"),
            (f"td2adaptor/{ROBOT}/wot-thing/DoorComponent/door", b'{"data":-1e999}', "/data"),  # as the WoT
            (f"td2adaptor/{ROBOT}/wot-thing/DoorComponent/door", b'{"data":NaN}', "/data"),  # consumer sent it
            (
                f"td2adaptor/{ROBOT}/DoorComponent/door/write",
                b'{"correlation":"\\ud800","payload":{"data":1}}',
                "/correlation",
            ),
        ]
        for topic, raw, _ in refused:
            app.send(topic, raw)
        app.wait(lambda ev: len(ev) >= len(refused), timeout=20)
        errors = app.of("error")
        assert [(e["payload"]["code"], e["payload"]["errors"][0]["path"]) for e in errors] == [
            ("invalid-event", path) for _, _, path in refused
        ]
        app.send(f"td2adaptor/{ROBOT}/DoorComponent/door/write", {"payload": {"data": 0.25}})
        assert sim.read_until("door 0.25", 10.0)
        assert [line for line in sim.lines[heard:] if line.startswith("door")] == ["door 0.25"]
    finally:
        engine.stop()
        bridge.close()


def test_a_ros1_bridge_that_cannot_import_the_adaptor_says_how_to_fix_it_in_words(
    master: Master, interfaces: Path
) -> None:
    """Issue 35: the ROS 1 interpreter's failure reached the user as `... did not start: ModuleNotFoundError: No
    module named ...`; it now says what `run` says on ROS 2, without a class name."""
    bridge = Ros1Bridge(
        Layout.of(rb1_model()),
        "no_such_adaptor",
        [(ROBOT, ROBOT)],
        python=harness.SYSTEM_PYTHON,
        pythonpath=[interfaces],
        master_uri=master.uri,
        timeout=5.0,
        environ=master.env(),
    )
    try:
        with pytest.raises(RosSetupError) as failed:
            bridge.start()
    finally:
        bridge.close()
    message = str(failed.value)
    assert "cannot import the adaptor package 'no_such_adaptor'" in message and "--package-path" in message
    assert not CLASS_NAME.search(message), message


def _group_members(pgid: int) -> list[int]:
    """Processes of a process group, from /proc."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid:
            found.append(int(stat.parent.name))
    return found


def rb1_bridge(model: Any, master: Master, interfaces: Path, package_src: Path, **options: Any) -> Ros1Bridge:
    """The RB-1 adaptor's ROS 1 bridge for ROBOT (not started yet)."""
    return Ros1Bridge(
        Layout.of(model),
        PKG,
        [(ROBOT, ROBOT)],
        python=harness.SYSTEM_PYTHON,
        pythonpath=[interfaces, package_src],
        master_uri=master.uri,
        environ=master.env(),
        **{"timeout": 5.0, **options},
    )


def _answering(port: Any) -> bool:
    """Whether the robot answers through the bridge yet (a failure is an answer: it ran no procedure yet)."""
    try:
        return _alive(port)
    except PortCallFailed:
        return True


def _alive(port: Any) -> bool:
    try:
        port.query("GoToComponent", "gotoQuery", -1, 2.0)
    except (PortUnavailable, PortTimeout):  # a bridge still starting may not answer in time yet
        return False
    return True


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory, package_src: Path) -> Path:
    """A catkin workspace with the generated package, built by Debian's catkin_make (as a ROS 1 user would)."""
    ws = tmp_path_factory.mktemp("catkin_ws")
    shutil.copytree(package_src.parent, ws / "src" / PKG, symlinks=True)
    build = subprocess.run(
        ["catkin_make", "-C", str(ws), f"-DPYTHON_EXECUTABLE={harness.SYSTEM_PYTHON}"],
        cwd=ws, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    assert os.access(ws / "devel" / "lib" / PKG / "edge_node", os.X_OK)
    return ws


def test_rosrun_edge_node_serves_a_robot_over_mosquitto(
    master: Master, sim: Sim, interfaces: Path, package_src: Path, workspace: Path, tmp_path: Path
) -> None:
    # `rosrun PKG edge_node ...` in the built workspace becomes `td2adaptor run --ros 1 --package PKG ...`
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"], client_id="edge-ros1-app")
    environ = {**os.environ, "ROS_HOME": str(master.home), "ROS_IP": "127.0.0.1", "ROS_HOSTNAME": "127.0.0.1"}
    environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{environ.get('PATH', '')}"  # td2adaptor
    rosrun = f'source {workspace}/devel/setup.bash && exec rosrun {PKG} edge_node "$@"'
    run = RunProcess(
        [
            str(EXAMPLE / "td.json"),
            "-I",
            str(EXAMPLE / "interfaces"),
            "--ros",
            "1",
            "--robot",
            ROBOT,
            "--bus",
            broker.url,
            "--master-uri",
            master.uri,
            "--ros1-python",
            harness.SYSTEM_PYTHON,
            "--package-path",
            str(package_src),
            "--package-path",
            str(interfaces),
            "--poll-period",
            "0.05",
            "--property-period",
            "0.05",
            "__name:=edge_node",  # what roslaunch adds: dropped by the script
        ],
        env=environ,
        command=["bash", "-c", rosrun, "edge_node"],
        new_session=True,
    )
    try:
        run.wait_ready()
        assert "via ROS 1 (a bridge under /usr/bin/python3)" in run.output()
        # the TD it publishes (retained) is the one `expose --ros 1` writes for this robot: ROS 1 time names
        exposed = CliRunner().invoke(
            cli, ["expose", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces"), "--robot", ROBOT,
                  "--broker", broker.url, "--ros", "1"],
        )  # fmt: skip
        assert exposed.exit_code == 0, exposed.output
        assert '"nsecs"' in exposed.output and '"nanosec"' not in exposed.output
        late = AppClient(broker.url, [f"td2adaptor/{ROBOT}/td"], client_id="edge-ros1-late")  # gets it retained
        try:
            (published,) = [e for _, e in late.wait(lambda ev: bool(ev), timeout=10)]
        finally:
            late.close()
        assert published == json.loads(exposed.output)
        goal = {"procedure": {"goals": [{"pose": {"x": 3.0, "y": 3.0, "theta": 0.0}}]}}
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "cli", "payload": goal})
        app.wait(terminal("feedback", "cli"), timeout=20)
        # `running` is what a query sees while the robot moves: on a loaded machine the first query can come after
        # the simulated robot's short move has ended
        states = [e["payload"]["state"] for e in feedback(app.events, "cli")]
        check_mission(
            app.events, "cli", ["queued", "running", "finished"] if "running" in states else ["queued", "finished"]
        )
        # SIGTERM to the whole process group, bridge included, as roslaunch or systemd stop a node: a clean
        # stop, with no property read reported as failed on the way out. The group's members get the signal
        # in no set order; the bridge first (and a moment of polling before the node's turn) is the worst case.
        members = [pid for pid in _group_members(run.proc.pid) if pid != run.proc.pid]
        assert members, "the ROS 1 bridge runs in the node's process group"
        for pid in members:
            os.kill(pid, signal.SIGTERM)
        time.sleep(0.5)  # ten property polls; a bridge that died of the signal would fail them
        assert run.terminate(signal.SIGTERM, group=True) == 0, run.output()
        assert "failed" not in run.output() and "PortUnavailable" not in run.output(), run.output()
        app.wait(
            lambda ev: [e["payload"]["state"] for t, e in ev if t.endswith("/status")][-1:] == ["offline"], timeout=10
        )
    finally:
        run.close()
        app.close()
        broker.stop()
    assert check_outbound(app.events, "ros1") > 0


def _roslaunch_env(master: Master, workspace: Path) -> dict[str, str]:
    """The environment of a ROS 1 user: the test's master, td2adaptor on PATH, the RB-1 message modules on
    PYTHONPATH (where a workspace holding them would put them); the workspace is sourced by the command."""
    environ = {k: v for k, v in os.environ.items() if not k.startswith("TD2ADAPTOR_")}
    environ.update(
        ROS_MASTER_URI=master.uri,
        ROS_HOME=str(master.home),
        ROS_LOG_DIR=str(master.home / "log"),
        ROS_IP="127.0.0.1",
        ROS_HOSTNAME="127.0.0.1",
        PYTHONPATH=str(harness.interfaces_dir()),
    )
    environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{environ.get('PATH', '')}"  # td2adaptor
    return environ


def test_roslaunch_command_line_leaves_empty_settings_out(master: Master, workspace: Path) -> None:
    # the command roslaunch builds for the node (its own `--args` code, which prints it unquoted), then
    # what the rosrun script makes of it: the empty optional settings are gone, the TD path stays one argument
    launch_file = workspace / "src" / PKG / "launch" / "edge_node.launch"
    script = workspace / "src" / PKG / "src" / PKG / "edge_node.py"
    code = (
        "import json, runpy, sys\n"
        "from roslaunch.node_args import get_node_args\n"
        "launch_file, script = sys.argv[1:3]\n"
        "sys.argv = ['roslaunch', *sys.argv[3:]]\n"
        "command = get_node_args('edge_node', [launch_file])\n"
        "ns = runpy.run_path(script)\n"
        "at = next(i for i, a in enumerate(command) if a.endswith('/edge_node'))\n"
        "print(json.dumps([command[:at], command[at], ns['launch_args'](ns['user_args'](command[at + 1:]))]))\n"
    )
    arguments = ["td:=/robots/my td.json", "robot:=r1", "interfaces:=/a:/b", "tls_ca_file:=/etc/ca.pem"]
    source = f'source {workspace}/devel/setup.bash && exec {harness.SYSTEM_PYTHON} -c "$@"'
    out = subprocess.run(
        ["bash", "-c", source, "python", code, str(launch_file), str(script), *arguments],
        env=_roslaunch_env(master, workspace), capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr
    environment, executable, args = json.loads(out.stdout.strip().splitlines()[-1])
    assert executable == f"{workspace}/devel/lib/{PKG}/edge_node"
    assert sorted(environment) == [
        'TD2ADAPTOR_ALLOW_INSECURE=""',
        'TD2ADAPTOR_TLS_CA_FILE="/etc/ca.pem"',
        'TD2ADAPTOR_TLS_CERT_FILE=""',
        'TD2ADAPTOR_TLS_KEY_FILE=""',
    ]
    assert args == ["/robots/my td.json", "--robot=r1", "--interfaces=/a", "--interfaces=/b", "--log-level=info"]


def test_roslaunch_edge_node_serves_a_robot_over_mosquitto_and_stops_on_sigint(
    master: Master, sim: Sim, workspace: Path, tmp_path: Path
) -> None:
    # `roslaunch PKG edge_node.launch ...` (Debian's roslaunch, on the test's master: --wait never starts
    # another) runs the rosrun script of the built workspace with the launch arguments; the optional ones
    # left empty (namespace, config, TLS files, allow_insecure) fall back to their defaults
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"], client_id="edge-ros1-launch-app")
    environ = _roslaunch_env(master, workspace)
    environ["TD2ADAPTOR_PROPERTY_PERIOD"] = "0.05"  # a setting the launch file leaves to the environment
    with xmlrpc.client.ServerProxy(master.uri) as proxy:  # what roscore sets and roslaunch --wait waits for
        proxy.setParam("/test", "/run_id", "edge-ros1-launch")
    roslaunch = f'source {workspace}/devel/setup.bash && exec roslaunch --wait {PKG} edge_node.launch "$@"'
    arguments = [f"td:={EXAMPLE / 'td.json'}", f"robot:={ROBOT}", f"bus:={broker.url}"]
    arguments += [f"interfaces:={EXAMPLE / 'interfaces'}", "poll_period:=0.05", "call_timeout:=5"]
    run = RunProcess(arguments, env=environ, command=["bash", "-c", roslaunch, "roslaunch"], new_session=True)
    try:
        run.wait_ready()
        assert f"serving {ROBOT} (namespace {ROBOT})" in run.output(), run.output()
        # (roslaunch runs the `td2adaptor` on PATH with the workspace's PYTHONPATH: the start line's words are
        # checked by the rosrun test, which runs this checkout)
        assert "/usr/bin/python3" in run.output() and "package robotnik_rb_1_adaptor" in run.output()
        goal = {"procedure": {"goals": [{"pose": {"x": 2.0, "y": 1.0, "theta": 0.0}}]}}
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "launch", "payload": goal})
        app.wait(terminal("feedback", "launch"), timeout=20)
        check_mission(app.events, "launch", ["queued", "running", "finished"])
        # Ctrl-C to roslaunch alone: it stops the node with SIGINT, and the robot goes offline
        assert run.terminate(signal.SIGINT, timeout=30) == 0, run.output()
        assert "td2adaptor run: stopped" in run.output(), run.output()
        app.wait(
            lambda ev: [e["payload"]["state"] for t, e in ev if t.endswith("/status")][-1:] == ["offline"], timeout=10
        )
        assert not [pid for pid in _group_members(run.proc.pid)], "roslaunch left processes behind"
    finally:
        run.close()
        app.close()
        broker.stop()
    assert check_outbound(app.events, "ros1") > 0
