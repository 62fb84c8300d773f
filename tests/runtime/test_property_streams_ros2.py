"""Property events per ROS message (`property_mode: message`, runtime/engine/streams.py) on real ROS 2 Jazzy (PyPI
wheels) and a real mosquitto, with the generated package spun as the edge node spins it: every
message becomes one event, in order, on the envelope and the WoT topic; a throttled property publishes the
latest message and never withholds the last one. No mocks.
"""

from __future__ import annotations

import importlib
import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

import td2adaptor
from td2adaptor.model.events import Kind, build_catalog
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.engine.streams import plain
from td2adaptor.runtime.events import EventValidator, encode, envelope
from td2adaptor.runtime.ros.genport import GeneratedPort, to_plain
from tests.conftest import REPO
from tests.ros2 import env
from tests.ros2.common import Process, build_rclpy
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

NAV_BASE = REPO / "examples" / "nav_base"


def stream_td(path: Path) -> Path:
    """examples/nav_base/td.json with only its odom and scan properties (standard messages only)."""
    td = json.loads((NAV_BASE / "td.json").read_text(encoding="utf-8"))
    td["actions"] = {}
    td["properties"] = {k: v for k, v in td["properties"].items() if k in ("odom", "scan")}
    # a package name of its own: tests/examples imports the whole example's `nav_base_adaptor` into the same
    # worker, and whichever of the two came first would otherwise be the other's too
    td["title"] = "Nav Base Streams"
    path.write_text(json.dumps(td), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def nav(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, ModuleType]:
    """The model and the imported rclpy adaptor of the odom + scan TD."""
    work = tmp_path_factory.mktemp("streams")
    result, src = build_rclpy(stream_td(work / "td.json"), work / "src", interfaces=NAV_BASE / "interfaces")
    sys.path.insert(0, str(src))
    return result.model, importlib.import_module(src.name)


@pytest.fixture(params=["single"])
def node(request: pytest.FixtureRequest, nav: tuple[Any, ModuleType]) -> Iterator[Any]:
    """A node of its own context, to be spun by the adaptor's spinner (`spin`) once the port made its entities."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    node: Any = rclpy.create_node(f"streams_{request.param}", context=context)
    spinners: list[Any] = []
    node.spin = lambda: spinners.append(nav[1].spin_in_background(node))
    try:
        yield node
    finally:
        for spinner in spinners:
            spinner.stop()
        node.destroy_node()
        rclpy.shutdown(context=context)


def sensors(robot: str, count: int, pause: float, repeats: int) -> Process:
    """The publisher of the numbered odometry messages, in a process of its own (tests/runtime/odom_publisher)."""
    args = [sys.executable, "-m", "tests.runtime.odom_publisher", robot, str(count), str(pause), str(repeats)]
    return Process(args, env.child_env([]))


def odometry(x: float) -> Any:
    from nav_msgs.msg import Odometry

    msg = Odometry()
    msg.header.frame_id = "odom"
    msg.pose.pose.position.x = x
    msg.pose.pose.orientation.w = 1.0
    return msg


def xs(app: AppClient, topic: str) -> list[float]:
    with app.cond:
        return [e["payload"]["pose"]["pose"]["position"]["x"] for t, e in app.events if t == topic]


def wot_xs(app: AppClient, topic: str) -> list[float]:
    with app.cond:
        return [e["pose"]["pose"]["position"]["x"] for t, e in app.events if t == topic]


def serve_streams(nav: tuple[Any, ModuleType], node: Any, robot: str, url: str, interval: float, qos: int = 1) -> Any:
    model, module = nav
    config = RuntimeConfig(
        robot=robot,
        bus=url,
        property_mode="message",
        property_interval=interval,
        property_qos=qos,
        state_dir="",
        td_broker=url,
    )
    port = GeneratedPort(model, module, robot, distro="ros2", node=node)
    node.spin()  # after the port made its subscriptions (as ros.connect_ros2 does)
    return serve(model, port, config)


def test_every_message_becomes_one_event_in_order(nav: tuple[Any, ModuleType], node: Any, broker: Mosquitto) -> None:
    robot = f"stream_all_{node.get_name().split('_')[-1]}"
    topic = f"td2adaptor/{robot}/BaseComponent/odom"
    wot = f"td2adaptor/{robot}/{WOT_LEVEL}/BaseComponent/odom"
    app = AppClient(broker.url, [topic, wot], client_id=f"streams-{robot}")
    engine = serve_streams(nav, node, robot, broker.url, 0.0)
    delivered: list[float] = []  # what the ROS subscription handed over (DDS may drop some on a loaded machine)
    payloads: list[Any] = []  # the same messages as the engine converts them when it reads no bytes
    streams = engine._streams
    assert streams is not None and all(s.convert is not plain for s in streams.slots), "read serialized"
    assert streams.out is None and all(s.out is None for s in streams.slots), "the robot's connection (MQTT 5)"

    def received(m: Any) -> None:
        delivered.append(m.pose.pose.position.x)
        payloads.append(to_plain(m))

    engine.port.watch_property("BaseComponent", "odom", received)
    count = 200  # then the last one 3 times more (equal: no event, property events report changes), then 200
    publisher = sensors(robot, count, 0.005, 3)
    try:
        publisher.wait_for(lambda e: e.get("event") == "sent", 60)
        app.wait(lambda _events: count in xs(app, topic), timeout=30)
        changes = [x for i, x in enumerate(delivered) if i == 0 or x != delivered[i - 1]]
        assert xs(app, topic) == changes
        with app.cond:  # the payloads the CDR decoder made are the ones to_plain gives, JSON text and all
            got = [json.dumps(e["payload"]) for t, e in app.events if t == topic]
        assert got == [json.dumps(p) for i, p in enumerate(payloads) if i == 0 or p != payloads[i - 1]]
        assert until(lambda: wot_xs(app, wot) == changes, 10.0)  # the WoT form too
        assert engine.stats.get("dropped.property", 0) == 0
        assert engine.stats["out.property"] == len(changes)
        assert len(delivered) > count / 2, "the subscription received most messages"
    finally:
        publisher.stop()
        engine.stop()
        app.close()
    # every event is an envelope the schemas accept, the same as the engine's own encoding would give
    catalog = build_catalog(nav[0])
    spec = catalog.find(Kind.PROPERTY, "odom")
    validator = EventValidator(catalog)
    events = [e for t, e in app.events if t == topic]
    assert [validator.errors(spec, e) for e in events[:3]] == [[], [], []]
    first = events[0]
    same = envelope(
        Kind.PROPERTY, robot=robot, source=f"td2adaptor/{robot}", payload=first["payload"], affordance="odom"
    )
    same.update(id=first["id"], time=first["time"])
    assert list(json.loads(encode(same))) == list(first)


def test_a_throttled_property_publishes_the_latest_and_never_withholds_the_last(
    nav: tuple[Any, ModuleType], node: Any, broker: Mosquitto
) -> None:
    robot = f"stream_slow_{node.get_name().split('_')[-1]}"
    topic = f"td2adaptor/{robot}/BaseComponent/odom"
    app = AppClient(broker.url, [topic], client_id=f"streams-{robot}")
    interval = 0.3
    engine = serve_streams(nav, node, robot, broker.url, interval)
    count = 40
    publisher = sensors(robot, count, 0.01, 0)
    try:
        # the last message comes out when its interval ends, though nothing follows it
        app.wait(lambda _events: float(count - 1) in xs(app, topic), timeout=60)
        sent = publisher.wait_for(lambda e: e.get("event") == "sent", 60)
    finally:
        publisher.stop()
        engine.stop()
        app.close()
    got = xs(app, topic)
    # the first goes out at once, before the first interval ends (the latest of what came meanwhile: on a loaded
    # machine messages 0 and 1 can arrive together, and then 1 is the latest)
    assert got[0] < interval / 0.01 and got[-1] == float(count - 1), got
    assert got == sorted(set(got)), "in order, each once"
    # at most one event per interval (plus the first, at once)
    assert len(got) <= 2 + math.ceil(sent["took"] / interval), (got, sent)


def test_property_qos_0_streams_at_qos_0(nav: tuple[Any, ModuleType], node: Any, broker: Mosquitto) -> None:
    """`property_qos: 0`: the stream's events (envelope and WoT form) travel at QoS 0, in order."""
    robot = f"stream_q0_{node.get_name().split('_')[-1]}"
    topic = f"td2adaptor/{robot}/BaseComponent/odom"
    wot = f"td2adaptor/{robot}/{WOT_LEVEL}/BaseComponent/odom"
    app = AppClient(broker.url, [topic, wot], client_id=f"streams-{robot}")
    engine = serve_streams(nav, node, robot, broker.url, 0.0, qos=0)
    count = 50
    publisher = sensors(robot, count, 0.01, 0)
    try:
        app.wait(lambda _events: float(count - 1) in xs(app, topic), timeout=60)
        assert until(lambda: float(count - 1) in wot_xs(app, wot), 10.0)
    finally:
        publisher.stop()
        engine.stop()
        app.close()
    got = xs(app, topic)
    assert got == sorted(set(got)) and engine.stats["out.property"] >= len(got)
    assert app.qos[topic] == app.qos[wot] == {0}, app.qos


def test_plain_gives_what_to_plain_gives(ros2_domain: int) -> None:
    """The stream's converter is a faster `to_plain`: the same values (NaN and infinities as None)."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan  # noqa: F401

    scan = LaserScan()
    scan.ranges = [1.0, math.nan, math.inf, 0.5]
    scan.intensities = [3.0]
    odom = odometry(2.5)
    odom.pose.covariance[0] = math.nan
    for msg in (scan, odom, Odometry()):
        assert plain(msg) == to_plain(msg)
    assert plain(scan)["ranges"] == [1.0, None, None, 0.5]
    json.dumps(plain(odom), allow_nan=False)
    assert td2adaptor  # the package under test is importable as installed
