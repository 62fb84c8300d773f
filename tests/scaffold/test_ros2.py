"""`td2adaptor scaffold ros2` on real ROS 2 Jazzy (PyPI wheels): the simulated RB-1 scaffolds to the example's
affordances; the scaffolded TD, untouched, is generated (rclpy) and served by `td2adaptor run`, and a
mission goes end to end over a real mosquitto; three namespaced robots give one Thing Model; a Fibonacci
action server (rclpy ActionServer) gives a ROS 2 action that the generated rclpy adaptor then drives; a bag
recorded here from the sim (rclpy subscriptions + rosbags' Writer) scaffolds without -I and generates.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from tests.conftest import EXAMPLE, REPO
from tests.ros2 import env
from tests.ros2.common import Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, check_mission
from tests.runtime.rb1 import GOAL, terminal
from tests.scaffold.common import (
    INTERFACES,
    compare_with_example,
    compiled_errors,
    example_td,
    scaffold,
    w3c_errors,
)

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix

ROBOT = "scaf_rb1"
FLEET = ("scaf_fleet_a", "scaf_fleet_b", "scaf_fleet_c")
ACTIONS = REPO / "tests" / "data" / "actions"


def started(args: list[str], environ: dict[str, str]) -> Process:
    process = Process(args, environ)
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=30)
    except BaseException:
        process.stop()
        raise
    return process


def sim(prefix: Path, namespaces: tuple[str, ...]) -> Process:
    """The simulated RB-1 (examples/robotnik_rb1/sim/ros2.py) serving `namespaces` (the first one's node
    also subscribes to the door)."""
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "0.5"]
    for ns in namespaces:
        args += ["--namespace", ns]
    return started(args, env.child_env([prefix]))


@pytest.fixture(scope="module")
def robot(rb1_prefix: Path) -> Iterator[Process]:
    process = sim(rb1_prefix, (ROBOT,))
    yield process
    process.stop()


@pytest.fixture(scope="module")
def fleet(rb1_prefix: Path) -> Iterator[Process]:
    process = sim(rb1_prefix, FLEET)
    yield process
    process.stop()


def _only(*namespaces: str) -> list[str]:
    """The robots' own nodes: other tests' nodes on the domain (an adaptor publishing the door, say) are
    not the robot."""
    return [arg for ns in namespaces for arg in ("--node", f"/{ns}/rb1_sim")]


@pytest.fixture(scope="module")
def scaffolded(robot: Process, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scaffold-ros2") / "td.json"
    done = scaffold(["ros2", "-I", str(INTERFACES), "--title", "Scaffolded RB-1", *_only(ROBOT)], out)
    assert done.code == 0, done.stderr
    assert "robot namespace: scaf_rb1" in done.stderr, done.stderr
    return out


def test_the_simulated_rb1_scaffolds_to_the_example_td(scaffolded: Path, tmp_path: Path) -> None:
    doc = json.loads(scaffolded.read_text(encoding="utf-8"))
    assert doc["@type"] == "Thing" and doc["title"] == "Scaffolded RB-1"
    compare_with_example(doc, example_td(), "ros2")
    assert doc["properties"]["command"]["forms"][0]["rosv:qos"] == {"durability": "transient_local"}
    assert compiled_errors(doc, tmp_path) == []
    assert w3c_errors(doc) == []
    # merged into the example, the graph changes nothing but what the graph cannot know (the door's depth)
    done = scaffold(["ros2", "-I", str(INTERFACES), "--merge", str(EXAMPLE / "td.json"), *_only(ROBOT)],
                    tmp_path / "merged.json")  # fmt: skip
    assert done.code == 0, done.stderr
    assert done.doc == example_td()


def test_the_scaffolded_td_is_generated_and_run_and_a_mission_goes_end_to_end(
    scaffolded: Path, rb1_prefix: Path, tmp_path: Path
) -> None:
    gen = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "gen", str(scaffolded), "-I", str(INTERFACES), "-b", "rclpy",
         "-o", str(tmp_path / "gen")],
        cwd=REPO, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert gen.returncode == 0, gen.stderr
    result = td2adaptor.compile(scaffolded, interfaces=[INTERFACES])
    assert result.model is not None
    package = result.model.package_name
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    app = AppClient(broker.url, [f"td2adaptor/{ROBOT}/#"], client_id="scaffold-ros2-app")
    args = [str(scaffolded), "-I", str(INTERFACES), "--robot", ROBOT, "--bus", broker.url,
            "--package-path", str(tmp_path / "gen" / "rclpy" / package), "--prefix", str(rb1_prefix),
            "--poll-period", "0.05", "--property-period", "0.2"]  # fmt: skip
    run = RunProcess(args, env=env.child_env([rb1_prefix]))
    try:
        run.wait_ready()
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "scaffolded", "payload": GOAL})
        app.wait(terminal("feedback", "scaffolded"), timeout=30)
        check_mission(app.events, "scaffolded", ["queued", "running", "finished"])

        # the scaffolded property (named after the topic) carries the robot's Status once it stands at cart 3
        def at_cart(events: list[tuple[str, dict[str, Any]]]) -> bool:
            return any(
                t == f"td2adaptor/{ROBOT}/StateComponent/state"
                and e["payload"]["robot_status"]["pose"]["pose"]["x"] == 1.5
                for t, e in events
            )

        app.wait(at_cart, timeout=15)
    finally:
        run.close()
        app.close()
        broker.stop()


def test_an_edge_node_running_beside_the_robot_is_not_the_robot(rb1_prefix: Path, tmp_path: Path) -> None:
    """`td2adaptor run` publishes the door command the robot subscribes to: scaffolded without --node, the
    door must stay the robot's write-only command, not become a read-only property of the edge node's.
    Robot, edge node and scaffold meet on a ROS domain of their own: on the worker's, an adaptor another test
    left publishing the door would be a (non-td2adaptor) publisher of it."""
    domain = {"ROS_DOMAIN_ID": str(env.private_domain_id())}
    gen = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "gen", str(EXAMPLE / "td.json"), "-I", str(INTERFACES), "-b", "rclpy",
         "-o", str(tmp_path / "gen")],
        cwd=REPO, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert gen.returncode == 0, gen.stderr
    result = td2adaptor.compile(EXAMPLE / "td.json", interfaces=[INTERFACES])
    assert result.model is not None
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    args = [str(EXAMPLE / "td.json"), "-I", str(INTERFACES), "--robot", ROBOT, "--bus", broker.url,
            "--package-path", str(tmp_path / "gen" / "rclpy" / result.model.package_name),
            "--prefix", str(rb1_prefix)]  # fmt: skip
    robot = started(
        [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "0.5", "--namespace", ROBOT],
        {**env.child_env([rb1_prefix]), **domain},
    )
    run = RunProcess(args, env={**env.child_env([rb1_prefix]), **domain})
    try:
        run.wait_ready()
        done = scaffold(
            ["ros2", "-I", str(INTERFACES), "--namespace", f"/{ROBOT}", "--namespace", "/door1"],
            tmp_path / "td.json",
            env={**env.child_env([rb1_prefix]), **domain},
        )
        assert done.code == 0, done.stderr
        doc = done.doc
        assert doc is not None
        door = doc["properties"]["command"]
        assert door.get("writeOnly") is True and "readOnly" not in door, door
        assert door["forms"][0]["rosv:role"] == "publisher" and door["forms"][0]["rosv:latch"] is True
        compare_with_example(doc, example_td(), "ros2")  # the robot's interface, and nothing of the edge node
        assert f"SCF115: left out td2adaptor's own node /td2adaptor_edge_{ROBOT}" in done.stderr, done.stderr
        # asked for by name, the edge node is scaffolded (what it publishes: the door, read from it)
        done = scaffold(
            ["ros2", "-I", str(INTERFACES), "--node", f"/td2adaptor_edge_{ROBOT}"],
            tmp_path / "edge.json",
            env={**env.child_env([rb1_prefix]), **domain},
        )
        assert done.code == 0 and "SCF115" not in done.stderr, done.stderr
        assert done.doc is not None and done.doc["properties"]["command"]["readOnly"] is True
    finally:
        run.close()
        broker.stop()
        robot.stop()


def test_three_namespaced_robots_give_one_thing_model(fleet: Process, tmp_path: Path) -> None:
    done = scaffold(["ros2", "-I", str(INTERFACES), "--title", "Robotnik RB-1", *_only(*FLEET)], tmp_path / "tm.json")
    assert done.code == 0, done.stderr
    tm = done.doc
    assert tm is not None and tm["@type"] == "tm:ThingModel", (done.stderr, tm)
    assert "scaf_fleet_a, scaf_fleet_b, scaf_fleet_c" in done.stderr
    model = json.loads((EXAMPLE / "rb1.tm.json").read_text(encoding="utf-8"))
    compare_with_example(tm, model, "ros2")
    assert w3c_errors(tm) == []
    assert compiled_errors(tm, tmp_path) == []
    # an instance for one of them is a TD of that robot
    instance = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "instantiate", str(tmp_path / "tm.json"),
         "--set", "robotName=scaf_fleet_b", "-o", str(tmp_path / "b.json")],
        cwd=REPO, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert instance.returncode == 0, instance.stderr
    td = json.loads((tmp_path / "b.json").read_text(encoding="utf-8"))
    assert td["@type"] == "Thing" and sorted(td["actions"]) == sorted(model["actions"])


def test_a_ros2_action_server_scaffolds_to_a_td_action_the_generated_adaptor_drives(
    ros2_domain: int, tmp_path: Path
) -> None:
    server = started([sys.executable, "-m", "tests.scaffold.fibonacci_server", "scaf_fibo"], env.child_env([]))
    try:
        args = ["ros2", "-I", str(ACTIONS), "--namespace", "/scaf_fibo", "--title", "Scaffolded Fibo"]
        done = scaffold(args, tmp_path / "td.json")
        assert done.code == 0, done.stderr
        doc = done.doc
        assert doc is not None and "properties" not in doc  # the action's hidden topics and services left out
        assert list(doc["actions"]) == ["fibonacci"]
        action = doc["actions"]["fibonacci"]
        form = action["forms"][0]
        assert (form["rosv:interface"], form["rosv:type"]) == ("action", "test_msgs/action/Fibonacci")
        assert form["rosv:name"] == "/scaf_fibo/fibonacci"  # one endpoint: no robot namespace is guessed
        assert action["input"] == {
            "type": "object",
            "properties": {"order": {"type": "integer", "minimum": -2147483648, "maximum": 2147483647}},
        }
        assert action["output"]["properties"]["sequence"]["type"] == "array"
        assert compiled_errors(doc, tmp_path, [ACTIONS]) == []
        assert w3c_errors(doc) == []
        # the scaffolded TD, untouched, generates an rclpy adaptor whose action client reaches the server
        assert _fibonacci(tmp_path / "td.json", tmp_path / "gen", 6) == [0, 1, 1, 2, 3, 5, 8]
    finally:
        server.stop()


def _fibonacci(td: Path, out: Path, order: int) -> list[int]:
    """Generate the rclpy adaptor of `td`, import it from its source and run one goal through it."""
    import importlib

    import rclpy
    from rclpy.context import Context

    from tests import generated

    model, package = generated.generate("rclpy", td, out, interfaces=[ACTIONS])
    sys.path.insert(0, str(package))
    adaptor: Any = importlib.import_module(model.package_name)
    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node("scaffold_fibo_client", context=context)
    spinner = adaptor.spin_in_background(node)
    try:
        component = adaptor.FibonacciComponent(node, "", timeout=10.0, wait_timeout=20.0)
        handle = component.send_fibonacci(component.construct_fibonacci_Goal(order=order))
        return list(handle.result(timeout=10.0).sequence)
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)


def _record(prefix: Path, namespace: str, bag: Path, seconds: float = 3.0) -> dict[str, int]:
    """Record a rosbag2 (MCAP, Jazzy's default) of the topics published under `namespace`, as `ros2 bag
    record` would (it is not in the pip wheels): an rclpy subscription per topic taking the serialized
    messages, QoS as offered, written with rosbags' Writer; the type definitions are those of the installed
    interface packages (`prefix/share/<pkg>/msg/*.msg`) and the Jazzy set. Returns messages per topic."""
    import importlib

    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for msg in sorted((prefix / "share").glob("*/msg/*.msg")):
        types.update(get_types_from_msg(msg.read_text(encoding="utf-8"), f"{msg.parts[-3]}/msg/{msg.stem}"))
    store.register(types)

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("scaffold_recorder", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    counts: dict[str, int] = {}
    try:
        deadline = time.monotonic() + 10
        topics: list[tuple[str, str]] = []
        while time.monotonic() < deadline and len(topics) < 2:  # the sim's state and markers
            executor.spin_once(timeout_sec=0.1)
            topics = [(name, kinds[0]) for name, kinds in node.get_topic_names_and_types()
                      if name.startswith(f"/{namespace}/") and node.count_publishers(name) > 0]  # fmt: skip
        assert len(topics) >= 2, topics
        zero = QosTime(0, 0)
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            for name, msgtype in topics:
                offered = node.get_publishers_info_by_topic(name)[0].qos_profile
                reliable = offered.reliability == ReliabilityPolicy.RELIABLE
                latched = offered.durability == DurabilityPolicy.TRANSIENT_LOCAL
                qos = Qos(QosHistory.KEEP_LAST, offered.depth,
                          QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
                          QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
                          zero, zero, QosLiveliness.AUTOMATIC, zero, False)  # fmt: skip
                conn = writer.add_connection(name, msgtype, typestore=store, offered_qos_profiles=[qos])
                package, _, short = msgtype.split("/")
                cls = getattr(importlib.import_module(f"{package}.msg"), short)
                counts[name] = 0

                def on_message(data: bytes, conn: Any = conn, name: str = name) -> None:
                    writer.write(conn, time.time_ns(), data)
                    counts[name] += 1

                profile = QoSProfile(depth=10, reliability=offered.reliability, durability=offered.durability)
                node.create_subscription(cls, name, on_message, profile, raw=True)
            stop = time.monotonic() + seconds
            while time.monotonic() < stop:
                executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    return counts


def test_a_bag_recorded_from_the_sim_scaffolds_without_interfaces_and_generates(
    robot: Process, rb1_prefix: Path, tmp_path: Path
) -> None:
    counts = _record(rb1_prefix, ROBOT, tmp_path / "recorded")
    assert counts and all(n > 0 for n in counts.values()), counts
    done = scaffold([str(tmp_path / "recorded"), "--title", "Recorded RB-1"], tmp_path / "td.json")  # no -I
    assert done.code == 0 and "(0 errors, 0 warnings)" in done.stderr, done.stderr
    doc = done.doc
    assert doc is not None and sorted(doc["properties"]) == ["arPoseMarker", "state"], doc
    # the recording's own definitions give the schemas: the example's, for the same Status topic
    state = doc["properties"]["state"]
    example = example_td()["properties"]["availability"]
    assert state["forms"][0]["rosv:name"] == "/{{robotName}}/robot_local_control/state"
    assert state["properties"].keys() == example["properties"].keys()
    markers = doc["properties"]["arPoseMarker"]["properties"]["markers"]
    assert markers["type"] == "array" and "pose" in markers["items"]["properties"]
    assert compiled_errors(doc, tmp_path) == []
    assert w3c_errors(doc) == []
    gen = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "gen", str(tmp_path / "td.json"), "-I", str(INTERFACES), "-b", "rclpy",
         "-o", str(tmp_path / "gen")],
        cwd=REPO, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert gen.returncode == 0, gen.stderr
    assert list((tmp_path / "gen" / "rclpy").iterdir()), "gen wrote nothing"
