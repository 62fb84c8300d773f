"""The dashboard's server-side pieces without a browser: which topics a robot's TD lets the page publish on,
where the map finds a robot's pose (the RB-1's and the nav_base's TDs as their edge nodes publish them), and the
bus connection's refusals, which never show a password."""

from __future__ import annotations

import math
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.dashboard.connection import BusSettings, open_dashboard_bus
from td2adaptor.dashboard.pose import find_pose, read_pose
from td2adaptor.dashboard.server import DashboardError, parse_listen
from td2adaptor.dashboard.tdforms import affordances
from td2adaptor.model.exposed import exposed_td
from td2adaptor.runtime.bus.security import SecurityError
from tests.conftest import REPO
from tests.ports import free_port
from tests.runtime.rb1 import rb1_model


def nav_base_td(robot: str) -> dict[str, Any]:
    example = REPO / "examples" / "nav_base"
    result = td2adaptor.compile(example / "td.json", interfaces=[example / "interfaces"])
    assert result.model is not None
    return exposed_td(result.model, robot=robot, broker="mqtt://127.0.0.1:1883")


def test_a_td_names_the_topics_the_page_may_publish_on_and_only_under_its_robot() -> None:
    td = exposed_td(rb1_model(), robot="r1", broker="mqtt://127.0.0.1:1883")
    topics = affordances(td, "td2adaptor/r1/")
    assert topics.publish[("gotoRun", "invokeaction")] == "td2adaptor/r1/wot-thing/GoToComponent/gotoRun"
    assert topics.publish[("gotoRun", "cancelaction")] == "td2adaptor/r1/wot-thing/GoToComponent/gotoCancel"
    assert topics.publish[("door", "writeproperty")] == "td2adaptor/r1/wot-thing/DoorComponent/door"
    assert topics.properties["td2adaptor/r1/wot-thing/PoseMarkerComponent/poseMarker"] == "poseMarker"
    assert topics.events["td2adaptor/r1/wot-thing/GoToComponent/gotoRun/feedback"] == "gotoRunFeedback"
    # a TD that names another robot's topics (or a wildcard) gets none of them
    td["actions"]["gotoRun"]["forms"][0]["mqv:topic"] = "td2adaptor/r2/wot-thing/GoToComponent/gotoRun"
    td["properties"]["poseMarker"]["forms"][0]["mqv:topic"] = "td2adaptor/r1/#"
    topics = affordances(td, "td2adaptor/r1/")
    assert ("gotoRun", "invokeaction") not in topics.publish
    assert "poseMarker" not in topics.properties.values()


def test_the_map_finds_the_pose_of_the_rb1_and_of_the_nav_base() -> None:
    rb1 = find_pose(exposed_td(rb1_model(), robot="r1", broker="mqtt://127.0.0.1:1883"))
    assert [(w.prop, w.path) for w in rb1] == [
        ("availability", ("localization_status", "pose", "pose")),
        ("availability", ("robot_status", "pose", "pose")),
    ]
    # the localization pose left unset (zeros): the robot status's is the robot's
    value = {"localization_status": {"pose": {"pose": {"x": 0.0, "y": 0.0, "theta": 0.0}}}}
    value["robot_status"] = {"pose": {"pose": {"x": 1.5, "y": -2.0, "theta": 0.25}}}
    assert read_pose(rb1, value) == (1.5, -2.0, 0.25)
    assert read_pose(rb1, {"robot_id": "x"}) is None
    nav = find_pose(nav_base_td("n1"))
    assert nav and nav[0].path[-1] == "position" and nav[0].heading == "quaternion", nav
    half = math.sqrt(0.5)  # a quarter turn about z
    where = {"position": {"x": 3.0, "y": 4.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": half, "w": half}}
    value = {}
    node = value
    for key in nav[0].path[:-1]:
        node = node.setdefault(key, {})
    node.update(where)
    x, y, theta = read_pose(nav, value) or (None, None, None)
    assert (x, y) == (3.0, 4.0) and theta is not None and abs(theta - math.pi / 2) < 1e-9


def test_the_bus_connection_refuses_what_the_edge_node_refuses_without_showing_the_password() -> None:
    with pytest.raises(SecurityError) as in_url:
        open_dashboard_bus(BusSettings("mqtt://viewer:S3cret-1@127.0.0.1:1883"), env={})
    assert "S3cret-1" not in str(in_url.value) and "TD2ADAPTOR_MQTT_PASSWORD" in str(in_url.value)
    env = {"TD2ADAPTOR_MQTT_USERNAME": "viewer", "TD2ADAPTOR_MQTT_PASSWORD": "S3cret-2"}
    with pytest.raises(SecurityError) as in_clear:
        open_dashboard_bus(BusSettings("mqtt://192.0.2.10:1883"), env=env)
    assert "in clear" in str(in_clear.value) and "S3cret-2" not in str(in_clear.value)
    bus = open_dashboard_bus(BusSettings("mqtt://127.0.0.1:1883"), env=env)
    assert bus.security.username == "viewer" and bus.clean_start


def test_listen_addresses() -> None:
    assert parse_listen("127.0.0.1:0").loopback and parse_listen("[::1]:8080").host == "::1"
    assert not parse_listen("0.0.0.0:8080").loopback
    for bad in ("8080", "localhost:", "host:http", "h:70000"):
        with pytest.raises(DashboardError):
            parse_listen(bad)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--bus", "mqtt://viewer:S3cret-3@127.0.0.1:1883"], "carries credentials"),
        (["--bus", "mqtt://127.0.0.1:1", "--listen", "0.0.0.0:0"], "not a loopback address"),
        (["--bus", "mqtt://127.0.0.1:1", "--listen", "8080"], "give HOST:PORT"),
        (["--bus", "mqtt://127.0.0.1:1", "--directory", "http://u:S3cret-3@tdd:5000"], "carries credentials"),
        (["--bus", f"mqtt://127.0.0.1:{free_port()}"], "cannot reach the MQTT broker"),
    ],
)
def test_the_command_refuses_in_one_line_without_a_traceback_or_the_password(args: list[str], words: str) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "td2adaptor", "dashboard", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 1, proc.stderr
    assert words in proc.stderr and "Traceback" not in proc.stderr and "S3cret-3" not in proc.stderr, proc.stderr
    assert proc.stderr.startswith("td2adaptor dashboard: ") and len(proc.stderr.strip().splitlines()) == 1


class Subscriptions:
    """Where a `Fleet` subscribes (what it is fed is given to its handlers by the test, as the bus would)."""

    def __init__(self) -> None:
        self.handlers: dict[str, Any] = {}

    def subscribe(self, pattern: str, handler: Any, *, qos: int = 1) -> None:
        self.handlers[pattern] = handler


def test_a_page_gets_every_event_the_latest_value_and_at_most_what_it_can_hold(monkeypatch: pytest.MonkeyPatch) -> None:
    import json as js

    from td2adaptor.dashboard import fleet as fleet_module
    from td2adaptor.runtime.bus.bus import Message

    bus = Subscriptions()
    fleet = fleet_module.Fleet()
    fleet.attach(bus)
    try:
        td = exposed_td(rb1_model(), robot="r1", broker="mqtt://127.0.0.1:1883")
        status = {"type": "status", "payload": {"state": "online", "presence": "robot-absent", "owner": "p1"}}
        bus.handlers["td2adaptor/+/status"](Message("td2adaptor/r1/status", js.dumps(status).encode(), True))
        bus.handlers["td2adaptor/+/td"](Message("td2adaptor/r1/td", js.dumps(td).encode(), True))
        woken: list[int] = []
        watcher, snapshot = fleet.watch("r1", lambda: woken.append(1))
        # the status as the robot says it, whatever its members (presence and owner are news to this page)
        assert snapshot["robots"][0]["status"]["presence"] == "robot-absent"
        wot = bus.handlers["td2adaptor/+/wot-thing/#"]
        prop = "td2adaptor/r1/wot-thing/PoseMarkerComponent/poseMarker"
        feedback = "td2adaptor/r1/wot-thing/GoToComponent/gotoRun/feedback"
        for seq in (1, 2, 3):
            wot(Message(prop, js.dumps({"markers": [{"id": seq}]}).encode()))
            wot(Message(feedback, js.dumps({"state": "running", "seq": seq, "terminal": False}).encode()))
        wot(Message("td2adaptor/r1/wot-thing/Nothing/here", b"{}"))  # no TD names it: dropped
        items = watcher.take()
        assert [i["data"]["seq"] for i in items if i["k"] == "event"] == [1, 2, 3]
        assert [i["value"] for i in items if i["k"] == "value"] == [{"markers": [{"id": 3}]}]
        assert len(items) == 4 and woken == [1]
        monkeypatch.setattr(fleet_module, "PENDING_KEPT", 5)
        for seq in range(20):
            wot(Message(feedback, js.dumps({"state": "running", "seq": seq, "terminal": False}).encode()))
        assert [i["data"]["seq"] for i in watcher.take()] == [15, 16, 17, 18, 19]
        bus.handlers["td2adaptor/+/td"](Message("td2adaptor/r1/td", b"", True))  # a clean stop clears it
        assert watcher.take() == [{"k": "gone", "robot": "r1"}] and fleet.summaries() == []
    finally:
        fleet.close()


def test_the_page_is_served_on_ipv6_loopback_and_answers_only_its_own_host_names(tmp_path: Path) -> None:
    from tests.dashboard.harness import dashboard
    from tests.runtime.broker import Mosquitto

    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    try:
        with dashboard(broker.url, "--listen", "[::1]:0") as dash:
            assert dash.url.startswith("http://[::1]:"), dash.url
            port = dash.url.rsplit(":", 1)[1].strip("/")
            for host, status in ((f"[::1]:{port}", 200), (f"localhost:{port}", 200), ("evil.example", 400)):
                request = urllib.request.Request(f"{dash.url}api/fleet", headers={"Host": host})
                try:
                    with urllib.request.urlopen(request, timeout=10) as answer:
                        got = answer.status
                except urllib.error.HTTPError as exc:
                    exc.close()
                    got = exc.code
                assert got == status, host
    finally:
        broker.stop()


def test_a_directory_page_that_links_to_another_origin_is_the_last_one_read() -> None:
    """The token goes to the directory only: a `rel="next"` link to another origin is not followed."""
    import http.server
    import json
    import threading

    from td2adaptor.dashboard.directory import DirectoryReader
    from td2adaptor.dashboard.fleet import Fleet

    asked: list[str] = []

    class Directory(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            asked.append(self.path)
            body = json.dumps([{"title": f"page {len(asked)}"}]).encode()
            self.send_response(200)
            self.send_header("Content-Type", "application/json")
            if self.path.startswith("/things?limit=") and len(asked) == 1:  # page 2 on this origin, then elsewhere
                self.send_header("Link", '</things?offset=1&limit=1>; rel="next", </things>; rel="canonical"')
            else:
                self.send_header("Link", '<http://elsewhere.invalid/things?offset=2>; rel="next"')
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *_args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Directory)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        reader = DirectoryReader(f"http://127.0.0.1:{server.server_port}", Fleet(), token="t0ken", page=1)
        assert [td["title"] for td in reader.read()] == ["page 1", "page 2"]
        assert asked == ["/things?limit=1", "/things?offset=1&limit=1"]
    finally:
        server.shutdown()
        server.server_close()
