"""The edge node on real ROS 2 Jazzy (PyPI wheels): `GeneratedPort` over the colcon-built rclpy adaptor
against the simulated RB-1, the engine over a real mosquitto (with a broker restart mid-mission), a robot
killed mid-mission, and `td2adaptor run` serving a fleet from the Thing Model. No mocks anywhere.

The simulated RB-1 of this module serves its own namespaces (edge_*), so it never shares a robot with the
other ROS 2 tests of the same worker.
"""

from __future__ import annotations

import ast
import json
import os
import py_compile
import re
import runpy
import signal
import sys
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

import pytest

from td2adaptor.runtime import (
    LocalBroker,
    NoValue,
    PortCallFailed,
    PortTimeout,
    PortUnavailable,
    RuntimeConfig,
    loop,
    serve,
)
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.ros.genport import GeneratedPort
from tests.conftest import REPO
from tests.ros2 import env
from tests.ros2.common import EXAMPLE, PACKAGE, Process, answered
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, bus_of, check_mission, feedback, until
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_model, terminal

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build, adaptor, ros_node

NAMESPACES = ("edge_port", "edge_mqtt", "edge_fleet_a", "edge_fleet_b", "edge_fleet_c", "edge_launch", "edge_quick")
DURATION = 1.0


def goto_topic(robot: str) -> str:
    return f"td2adaptor/{robot}/GoToComponent/gotoRun"


def sim_process(prefix: Path, namespaces: tuple[str, ...], duration: float) -> Process:
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", str(duration)]
    for ns in namespaces:
        args += ["--namespace", ns]
    process = Process(args, env.child_env([prefix]))
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
    except BaseException:
        process.stop()
        raise
    return process


@pytest.fixture(scope="module")
def edge_sim(rb1_prefix: Path) -> Iterator[Process]:
    process = sim_process(rb1_prefix, NAMESPACES, DURATION)
    yield process
    process.stop()


def port_for(adaptor: ModuleType, node: Any, namespace: str, timeout: float = 5.0, wait: float = 10.0) -> GeneratedPort:
    return GeneratedPort(rb1_model(), adaptor, namespace, distro="ros2", node=node, timeout=timeout, wait_timeout=wait)


def answers(port: GeneratedPort) -> bool:
    """Whether the robot answers a query yet (`answered`; a query of no mission is refused: an answer too)."""
    return answered(
        lambda: port.query("GoToComponent", "gotoQuery", -1, 1.0), (PortUnavailable, PortTimeout), PortCallFailed
    )


def test_generated_port_drives_the_simulated_rb1(adaptor: ModuleType, ros_node: Any, edge_sim: Process) -> None:
    port = port_for(adaptor, ros_node, "edge_port")
    assert until(lambda: answers(port), 20.0, 0.1)
    goal = {"procedure": {"goals": [{"header": {"frame_id": "map"}, "pose": {"x": 1.5, "y": 3.0, "theta": 0.0}}]}}
    started = port.start("GoToComponent", "gotoRun", goal, 5.0)
    assert started.mission_id is not None and started.mission_id > 0
    assert started.response["state"]["current_state"] == "queued"
    assert started.response["state"]["header"]["id"] == started.mission_id
    json.dumps(started.response, allow_nan=False)  # plain JSON data, stamps as {sec, nanosec}
    assert set(started.response["state"]["header"]["stamp"]) == {"sec", "nanosec"}
    # a second run while busy: the robot's refusal, carried by the error
    with pytest.raises(PortCallFailed, match="already running a procedure") as busy:
        port.start("GoToComponent", "gotoRun", {}, 5.0)
    assert busy.value.response is not None and busy.value.response["state"]["current_state"] == "unknown"

    def query() -> dict[str, Any]:
        return dict(port.query("GoToComponent", "gotoQuery", started.mission_id or -1, 5.0))

    assert until(lambda: query()["state"]["current_state"] == "finished", 10.0)
    done = query()
    assert done["state"]["header"]["id"] == started.mission_id
    assert (done["state"]["last_event"], done["result"]["message"]) == ("finish", "Perfect")
    with pytest.raises(PortCallFailed, match="no procedure with id 4242") as unknown:
        port.query("GoToComponent", "gotoQuery", 4242, 5.0)
    assert unknown.value.response is not None and unknown.value.response["state"]["current_state"] == "unknown"

    # the robot stands at cart 3 now: robot_local_control/state (Status) and AlvarMarkers say so
    def status() -> Any:
        return port.read_property("AvailabilityComponent", "availability", 5.0)

    assert until(lambda: status()["robot_status"]["pose"]["pose"]["x"] == 1.5, 5.0)
    assert (status()["robot_id"], status()["operation_state"]) == ("edge_port", "idle")

    # the marker topic is published on its own timer: it may lag the Status by one period
    def marker_ids() -> list[int]:
        return [m["id"] for m in port.read_property("PoseMarkerComponent", "poseMarker", 5.0)["markers"]]

    assert until(lambda: marker_ids() == [3], 5.0)
    markers = port.read_property("PoseMarkerComponent", "poseMarker", 5.0)
    assert markers["markers"][0]["pose"]["pose"]["orientation"]["w"] == 1.0

    # cancel by the mission id the robot returned. A mission lasts DURATION (1 s): on a machine busier than its
    # cores the cancel can come after the pick finished, and the robot rightly answers finished/finish (seen in
    # a CI run); a new pick is then cancelled, up to three
    for _ in range(3):
        pick = port.start("PickComponent", "pickRun", {"procedure": {"pick_frame_id": "edge_port_cart3_contact"}}, 5.0)
        assert pick.mission_id is not None and pick.mission_id > started.mission_id
        cancelled = port.cancel("PickComponent", "pickCancel", pick.mission_id, 5.0)
        assert cancelled["state"]["header"]["id"] == pick.mission_id
        if cancelled["state"]["last_event"] != "finish":
            break
    assert (cancelled["state"]["current_state"], cancelled["state"]["last_event"]) == ("finished", "cancel")
    edge_sim.wait_for(lambda e: e.get("op") == "cancel" and e.get("id") == pick.mission_id, timeout=5.0)

    # the door: a publisher property (latched); the simulation hears the command
    port.write_property("DoorComponent", "door", {"data": 0.25})
    assert edge_sim.wait_for(lambda e: e.get("event") == "door" and e.get("value") == 0.25, timeout=10.0)
    # a payload the request type does not have is a failed call, not a crash
    with pytest.raises(PortCallFailed, match="no field bogus"):
        port.start("GoToComponent", "gotoRun", {"procedure": {"bogus": 1}}, 5.0)

    # a robot that is not there: unavailable within the wait timeout; a silent topic: no value
    nobody = port_for(adaptor, ros_node, "edge_nobody", timeout=0.3, wait=0.3)
    begin = time.monotonic()
    with pytest.raises(PortUnavailable):
        nobody.query("GoToComponent", "gotoQuery", -1, 0.3)
    assert time.monotonic() - begin < 3.0
    with pytest.raises(NoValue):
        nobody.read_property("AvailabilityComponent", "availability", 0.2)


def test_engine_over_mosquitto_on_ros2_survives_a_broker_restart(
    adaptor: ModuleType, ros_node: Any, edge_sim: Process, broker: Mosquitto
) -> None:
    robot = "edge_mqtt"
    model = rb1_model()
    config = RuntimeConfig(
        robot=robot, bus=broker.url, poll_period=0.05, property_period=0.2, call_timeout=5.0, mission_timeout=30.0
    )
    engine = serve(model, port_for(adaptor, ros_node, robot), config)
    app = AppClient(broker.url, [f"td2adaptor/{robot}/#"], client_id="edge-ros2-app")
    try:
        app.send(goto_topic(robot), {"id": "e-first", "correlation": "first", "source": "test", "payload": GOAL})
        app.wait(terminal("feedback", "first"), timeout=20)
        first = check_mission(app.events, "first", ["queued", "running", "finished"])
        assert first[-1]["payload"]["message"] == "Perfect" and first[0]["mission"] > 0
        # property events carry what ROS publishes (and conform to their schemas: check_outbound below)
        app.wait(
            lambda ev: any(
                t.endswith("/PoseMarkerComponent/poseMarker")
                and "wot-thing" not in t
                and [m["id"] for m in e["payload"]["markers"]] == [3]
                for t, e in ev
            ),
            timeout=10,
        )
        # the broker goes away mid-mission and comes back: the mission completes, no feedback is lost
        second_goal = {"procedure": {"goals": [{"pose": {"x": 3.0, "y": 3.0, "theta": 0.0}}]}}
        app.send(goto_topic(robot), {"correlation": "second", "payload": second_goal})
        app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, "second")], timeout=10)
        broker.stop()
        time.sleep(DURATION + 0.4)  # the procedure ends on the robot meanwhile; "finished" waits in the client
        assert isinstance(bus_of(engine), MqttBus) and not bus_of(engine).connected
        broker.start()
        app.wait(terminal("feedback", "second"), timeout=20)
        check_mission(app.events, "second", ["queued", "running", "finished"])
        assert isinstance(bus_of(engine), MqttBus) and bus_of(engine).connects >= 2
    finally:
        engine.stop()
        app.close()
    check_outbound(app.events)


def test_queries_and_a_procedures_calls_are_answered_on_the_responses_reader_without_the_call_pool(
    adaptor: ModuleType, ros_node: Any, edge_sim: Process, broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On ROS 2 the engine sends a query, a cancel and a procedure's start, polls and cancel from its loop
    (`call_<action>_then`), and the answer is published on the responses reader's thread: no call-pool thread
    is woken for them (one thread hand-off fewer each way)."""
    robot = "edge_quick"
    port = port_for(adaptor, ros_node, robot)
    assert until(lambda: answers(port), 20.0, 0.1)
    pooled: list[str] = []  # the robot's calls handed to the call pool (its lane), by the thread that did
    submit = loop.Lane.submit

    def counted(lane: loop.Lane, task: Any) -> None:
        pooled.append(threading.current_thread().name)
        submit(lane, task)

    published: list[tuple[str, str]] = []  # (event kind, thread)
    send = Outbox.send

    def recorded(outbox: Outbox, spec: Any, data: bytes, **kw: Any) -> None:
        published.append((spec.kind.value, threading.current_thread().name))
        send(outbox, spec, data, **kw)

    monkeypatch.setattr(loop.Lane, "submit", counted)
    monkeypatch.setattr(Outbox, "send", recorded)
    config = RuntimeConfig(robot=robot, bus=broker.url, poll_period=0.05, property_period=0, call_timeout=5.0)
    engine = serve(rb1_model(), port, config)
    app = AppClient(broker.url, [f"td2adaptor/{robot}/#"], client_id="edge-quick-app")
    root = f"td2adaptor/{robot}"
    try:
        app.send(goto_topic(robot), {"correlation": "go", "payload": GOAL})
        app.wait(terminal("feedback", "go"), timeout=20)
        mission = check_mission(app.events, "go", ["queued", "running", "finished"])[0]["mission"]

        def answered(correlation: str) -> None:
            app.wait(lambda ev: any(e.get("type") == "state" and e.get("correlation") == correlation for _, e in ev))

        # one at a time: calls that overlap are made on the pool (a pool thread publishes one answer while the
        # reader takes the next)
        app.send(f"{root}/GoToComponent/gotoQuery", {"correlation": "q", "mission": mission})
        answered("q")
        app.send(f"{root}/GoToComponent/gotoQuery", {"correlation": "unknown", "mission": 4242})
        answered("unknown")
        pick = {"procedure": {"pick_frame_id": "edge_quick_cart3_contact"}}
        app.send(f"{root}/PickComponent/pickRun", {"correlation": "pick", "payload": pick})
        app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, "pick")], timeout=10)
        app.send(f"{root}/PickComponent/pickCancel", {"correlation": "stop"})
        app.wait(terminal("feedback", "pick"), timeout=20)
        app.send(f"{root}/GoToComponent/gotoCancel", {"correlation": "c", "mission": 4343})
        answered("c")
    finally:
        engine.stop()
        app.close()
    states = {e.get("correlation"): e["payload"] for _, e in app.events if e.get("type") == "state"}
    assert states["q"]["state"] == "finished", states
    assert states["unknown"]["message"] == "no procedure with id 4242", states  # the robot's answer, read
    assert states["c"]["message"] == "no procedure with id 4343", states
    assert feedback(app.events, "pick")[-1]["payload"]["state"] in ("finished", "cancelled")
    assert pooled == [], f"calls handed to the call pool: {len(pooled)}"
    answers_threads = {thread for kind, thread in published if kind in ("feedback", "state")}
    assert answers_threads == {"adaptor-responses"}, published


def test_a_robot_killed_mid_mission_gives_failure_feedback_within_the_timeout(
    adaptor: ModuleType, ros_node: Any, rb1_prefix: Path
) -> None:
    robot = "edge_doomed"
    sim = sim_process(rb1_prefix, (robot,), 30.0)
    try:
        model = rb1_model()
        config = RuntimeConfig(robot=robot, poll_period=0.1, call_timeout=1.0, mission_timeout=15.0, property_period=0)
        # as `td2adaptor run` makes it: the wait for a (re)appearing service is bounded by the call timeout too
        port = port_for(adaptor, ros_node, robot, timeout=config.call_timeout, wait=config.call_timeout)

        assert until(lambda: answers(port), 20.0, 0.1)
        broker = LocalBroker()
        app = LocalApp(broker)
        engine = serve(model, port, config, broker=broker)
        try:
            app.send(goto_topic(robot), {"correlation": "doomed", "payload": GOAL})
            app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, "doomed")], timeout=10)
            killed = time.monotonic()
            sim.proc.send_signal(signal.SIGKILL)
            sim.proc.wait(10)
            app.wait(terminal("feedback", "doomed"), timeout=config.mission_timeout + 5)
            elapsed = time.monotonic() - killed
            last = feedback(app.events, "doomed")[-1]["payload"]
            assert (last["state"], last["reason"]) == ("failed", "unreachable"), last
            assert "did not answer 3 queries" in last["message"]
            assert elapsed < config.mission_timeout, elapsed  # the robot's absence, not the mission timeout
            assert len([e for e in feedback(app.events, "doomed") if e["payload"]["terminal"]]) == 1
        finally:
            engine.stop()
        check_outbound(app.events)
    finally:
        sim.stop()


def test_the_generated_entry_point_serves_a_fleet_from_the_thing_model_and_stops_cleanly(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, edge_sim: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    robots = {"fleet_1": "edge_fleet_a", "fleet_2": "edge_fleet_b", "fleet_3": "edge_fleet_c"}
    fleet = tmp_path / "fleet.yaml"
    lines = [f"bus: {broker.url}", "poll_period: 0.05", "property_period: 0", "call_timeout: 10", "robots:"]
    lines += [f"  - {{robot: {r}, namespace: {ns}}}" for r, ns in robots.items()]
    fleet.write_text("\n".join(lines) + "\n", encoding="utf-8")
    app = AppClient(broker.url, ["td2adaptor/#"], client_id="edge-fleet-app")
    # the colcon-installed package's console script (`ros2 run robotnik_rb_1_adaptor edge_node`) becomes
    # `td2adaptor run --ros 2 --package robotnik_rb_1_adaptor ...`; the environment is that of sourced install
    # spaces (interfaces and adaptor on PYTHONPATH and LD_LIBRARY_PATH), so no --prefix is needed
    entry_point = adaptor_build[1] / "lib" / PACKAGE / "edge_node"
    assert entry_point.is_file()
    environ = env.child_env([rb1_prefix, adaptor_build[1]])
    environ["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), environ["PATH"]])
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--config", str(fleet)]
    args += ["--ros-args", "-r", "__node:=edge_node"]  # what `ros2 launch` appends: dropped by the entry point
    run = RunProcess(args, env=environ, command=[str(entry_point)])
    try:
        run.wait_ready()
        assert "serving fleet_1 (namespace edge_fleet_a), fleet_2" in run.output()
        assert f"package {PACKAGE}" in run.output()

        def tds_of(ev: list[tuple[str, dict[str, Any]]], robot: str) -> list[dict[str, Any]]:
            return [e for t, e in ev if t == f"td2adaptor/{robot}/td"]

        def statuses(ev: list[tuple[str, dict[str, Any]]], robot: str) -> list[str]:
            return [e["payload"]["state"] for t, e in ev if t == f"td2adaptor/{robot}/status"]

        app.wait(lambda ev: all(statuses(ev, r)[-1:] == ["online"] for r in robots), timeout=20)
        for robot in robots:
            app.send(goto_topic(robot), {"correlation": f"go-{robot}", "payload": GOAL})
        for robot in robots:
            app.wait(terminal("feedback", f"go-{robot}"), timeout=30)
            check_mission(app.events, f"go-{robot}", ["queued", "running", "finished"])
        assert run.terminate(signal.SIGTERM) == 0, run.output()
        app.wait(lambda ev: all(statuses(ev, r)[-1:] == ["offline"] for r in robots), timeout=10)
        assert "td2adaptor run: stopped" in run.output()
        # each robot's TD was retained while it ran (its own id, the bus as broker), then cleared
        for robot in robots:
            tds = app.wait(lambda ev, r=robot: tds_of(ev, r)[-1:] == [{"raw": ""}], timeout=10)
            (td,) = [e for e in tds_of(tds, robot) if e != {"raw": ""}][:1]
            assert td["@type"] == "Thing" and td["id"].endswith(f":{robot}")
            # an instance of the Thing Model it was run from: linked as its type, not its instructions repeated
            assert td["links"] == [{"rel": "type", "href": "rb1.tm.json", "type": "application/tm+json"}]
            assert "instantiate" not in td["description"], td["description"]
            wot = goto_topic(robot).replace(f"/{robot}/", f"/{robot}/wot-thing/")  # the WoT topic of gotoRun
            assert td["actions"]["gotoRun"]["forms"][0]["href"] == f"{broker.url}/{wot}"
    finally:
        run.close()
        app.close()
    check_outbound(app.events)


# ---------------------------------------------------------------------------------------------------------
# the launch file (launch/edge_node.launch.py). ROS 2's launch and launch_ros are not in the PyPI wheels
# this machine has, so `ros2 launch` cannot run here: the file is checked as source (it compiles, declares
# the documented arguments, names the installed console script), and its generate_launch_description() runs
# against minimal stand-ins of launch/launch_ros that only record what it builds (_stand_in_launch), to see
# which arguments reach the node's command line and environment. Everything after that is real.


def _launch_file(install: Path) -> Path:
    return install / "share" / PACKAGE / "launch" / "edge_node.launch.py"


def _documented_arguments(readme: str) -> list[str]:
    section = readme.split("## Launch file", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `(\w+)` \|", section, re.MULTILINE)


def test_the_launch_file_is_installed_and_names_the_entry_point_and_the_documented_arguments(
    adaptor_build: tuple[Path, Path], tmp_path: Path
) -> None:
    src, install = adaptor_build
    launch = _launch_file(install)
    assert launch.read_bytes() == (src / "launch" / "edge_node.launch.py").read_bytes()
    py_compile.compile(str(launch), cfile=str(tmp_path / "launch.pyc"), doraise=True)
    tree = ast.parse(launch.read_text(encoding="utf-8"))
    tables = {
        target.id: ast.literal_eval(node.value)
        for node in tree.body
        if isinstance(node, ast.Assign)
        for target in node.targets
        if isinstance(target, ast.Name)
    }
    names = [name for name, _default, _text in tables["ARGUMENTS"]]
    readme = (install / "share" / PACKAGE / "README.md").read_text(encoding="utf-8")
    assert names == _documented_arguments(readme)
    assert [name for name, default, _text in tables["ARGUMENTS"] if default is None] == ["td", "robot"]
    assert sorted(["td", *tables["OPTIONS"], *tables["ENVIRONMENT"]]) == sorted(names)  # each reaches the node
    # the same arguments as the ROS 1 package's launch file, in the same order
    ros1 = ET.parse(REPO / "generated" / "rospy" / PACKAGE / "launch" / "edge_node.launch").getroot()
    assert [arg.get("name") for arg in ros1.iter("arg")] == names
    # Node(package=PACKAGE, executable="edge_node"): the console script colcon installed to lib/PACKAGE/
    (node,) = [c for c in ast.walk(tree) if isinstance(c, ast.Call) and getattr(c.func, "id", "") == "Node"]
    keywords = {k.arg: k.value for k in node.keywords}
    assert ast.literal_eval(keywords["package"]) == PACKAGE
    assert ast.literal_eval(keywords["executable"]) == "edge_node"
    assert os.access(install / "lib" / PACKAGE / "edge_node", os.X_OK)
    script = (install / "lib" / PACKAGE / "edge_node").read_text(encoding="utf-8")
    assert "'console_scripts', 'edge_node'" in script  # setup.py's edge_node = PACKAGE.edge_node:main


class _Substitution:
    pass


class _LaunchConfiguration(_Substitution):
    def __init__(self, variable_name: str, *, default: Any = None) -> None:
        self.name = variable_name


class _Recorded:
    """An action of the stand-in: what it was constructed with."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


def _stand_in_launch(
    launch: Path, given: dict[str, str], install: Path, monkeypatch: pytest.MonkeyPatch
) -> tuple[list[str], dict[str, str]]:
    """The node's command line and additional environment for launch arguments `given`, as launch_ros would
    make them: the launch file's own generate_launch_description() against recording stand-ins of launch and
    launch_ros (a stand-in: the real packages are not installable here), substitutions resolved by name."""
    modules = {
        "launch": SimpleNamespace(LaunchDescription=_Recorded),
        "launch.actions": SimpleNamespace(DeclareLaunchArgument=_Recorded),
        "launch.substitutions": SimpleNamespace(LaunchConfiguration=_LaunchConfiguration),
        "launch_ros": SimpleNamespace(),
        "launch_ros.actions": SimpleNamespace(Node=_Recorded),
    }
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    description = runpy.run_path(str(launch))["generate_launch_description"]()
    (entities,) = description.args
    declared = [e for e in entities if "default_value" in e.kwargs]
    (node,) = [e for e in entities if "executable" in e.kwargs]
    unknown = set(given) - {d.args[0] for d in declared}
    assert not unknown, f"not arguments of the launch file: {unknown}"
    values = {d.args[0]: given.get(d.args[0], d.kwargs["default_value"]) for d in declared}
    missing = [name for name, value in values.items() if value is None]
    assert not missing, f"required arguments not given: {missing}"

    def text(item: Any) -> str:
        if isinstance(item, str):
            return item
        if isinstance(item, _LaunchConfiguration):
            return str(values[item.name])
        return "".join(text(part) for part in item)

    executable = install / "lib" / text(node.kwargs["package"]) / text(node.kwargs["executable"])
    command = [str(executable), *(text(a) for a in node.kwargs["arguments"])]
    environment = {text(k): text(v) for k, v in node.kwargs["additional_env"].items()}
    return command, environment


def test_the_launch_file_starts_the_entry_point_with_its_arguments_and_it_serves_the_robot(
    adaptor_build: tuple[Path, Path],
    rb1_prefix: Path,
    edge_sim: Process,
    broker: Mosquitto,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    robot = "edge_launch"  # no namespace argument: the robot id is the namespace
    given = {"td": str(EXAMPLE / "td.json"), "robot": robot, "bus": broker.url, "poll_period": "0.05"}
    given["interfaces"] = str(EXAMPLE / "interfaces")
    command, environment = _stand_in_launch(_launch_file(adaptor_build[1]), given, adaptor_build[1], monkeypatch)
    assert command[0] == str(adaptor_build[1] / "lib" / PACKAGE / "edge_node")
    assert command[1:] == [
        given["td"],
        f"--robot={robot}",
        "--namespace=",
        f"--bus={broker.url}",
        f"--interfaces={given['interfaces']}",
        "--config=",
        "--call-timeout=",
        "--poll-period=0.05",
        "--log-level=info",
    ]
    variables = ("TD2ADAPTOR_ALLOW_INSECURE", "TD2ADAPTOR_TLS_CA_FILE", "TD2ADAPTOR_TLS_CERT_FILE")
    assert environment == dict.fromkeys((*variables, "TD2ADAPTOR_TLS_KEY_FILE"), "")
    # from here on real: the installed entry point with that command line and environment (plus the ROS
    # arguments launch_ros appends), on ROS 2 and mosquitto; the empty settings must not get in the way
    app = AppClient(broker.url, [f"td2adaptor/{robot}/#"], client_id="edge-launch-app")
    environ = {
        k: v for k, v in env.child_env([rb1_prefix, adaptor_build[1]]).items() if not k.startswith("TD2ADAPTOR_")
    }
    environ["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), environ["PATH"]])
    environ.update(environment, TD2ADAPTOR_PROPERTY_PERIOD="0")
    run = RunProcess([*command[1:], "--ros-args", "-r", "__node:=edge_node"], env=environ, command=command[:1])
    try:
        run.wait_ready()
        assert f"serving {robot} (namespace {robot}) on {broker.url}" in run.output(), run.output()
        app.send(goto_topic(robot), {"correlation": "launch", "payload": GOAL})
        app.wait(terminal("feedback", "launch"), timeout=30)
        check_mission(app.events, "launch", ["queued", "running", "finished"])
        assert run.terminate(signal.SIGINT) == 0, run.output()
        app.wait(lambda ev: [e["payload"]["state"] for t, e in ev if t.endswith("/status")][-1:] == ["offline"])
    finally:
        run.close()
        app.close()
    check_outbound(app.events)
