"""The generated rospy package against real ROS 1 (Debian's rospy + rosmaster, no mocks): the simulated RB-1
scenario, and every error path for real. ROS code runs under /usr/bin/python3 in subprocesses (see
tests/ros1/harness.py); one private master per test module (per xdist worker).
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from tests import generated
from tests.conftest import EXAMPLE
from tests.ros1 import harness
from tests.ros1.harness import Master

PKG = "robotnik_rb_1_adaptor"


@pytest.fixture(scope="module")
def package(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    """The RB-1 rospy package, generated into a temporary directory; returns the package directory."""
    _, package = generated.generate(
        "rospy", EXAMPLE / "td.json", tmp_path_factory.mktemp("rospy"), interfaces=[EXAMPLE / "interfaces"]
    )
    assert package.name == PKG
    return package


@pytest.fixture(scope="module")
def interfaces(ros1: None) -> Path:
    return harness.interfaces_dir()


@pytest.fixture(scope="module")
def path(package: Path, interfaces: Path) -> list[Path]:
    return [interfaces, package / "src"]


def test_package_xml_validates_with_catkin_pkg_and_imports_under_debian_rospy(package: Path, path: list[Path]) -> None:
    check = harness.run_system_python(
        "import sys\n"
        "from catkin_pkg.package import parse_package\n"
        "p = parse_package(sys.argv[1])\n"
        "p.validate()\n"
        "deps = sorted(d.name for d in p.exec_depends)\n"
        "assert deps == sorted([d.name for d in p.build_depends] + ['roslaunch', 'rosgraph']), deps\n"
        "print(p.name, p.package_format, ' '.join(deps))\n",
        str(package / "package.xml"),
    )
    assert check.returncode == 0, check.stderr
    name, fmt, *deps = check.stdout.split()
    assert (name, fmt) == (PKG, "2")
    assert {"rospy", "procedures_msgs", "robot_local_control_msgs", "std_msgs", "ar_track_alvar_msgs"} <= set(deps)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(map(str, path)))
    code = (
        "import rospy, robotnik_rb_1_adaptor as a\n"
        "from robotnik_rb_1_adaptor import errors\n"
        "print(sorted(n for n in a.__all__ if n.endswith('Component')))\n"
        "try:\n"
        "    a.GoToComponent('bad name')\n"
        "except a.InvalidRobotName as e:\n"
        "    print('invalid', isinstance(e, ValueError) and isinstance(e, errors.AdaptorError))\n"
        "try:\n"
        "    a.DoorComponent().register()\n"
        "except a.NotInitialized:\n"
        "    print('not initialized')\n"
        "print(a.GoToComponent('/rb1_base_a/')._svc_gotoRun.name)\n"
    )
    out = subprocess.run([harness.SYSTEM_PYTHON, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == [
        str(sorted(backend_components())),
        "invalid True",
        "not initialized",
        "/rb1_base_a/robot_local_control/NavigationComponent/GoToComponent/add",
    ]


def backend_components() -> list[str]:
    return [
        "AvailabilityComponent",
        "DoorComponent",
        "GoToComponent",
        "PickComponent",
        "PlaceComponent",
        "PoseMarkerComponent",
    ]


SCENARIO = """
from robotnik_rb_1_adaptor import *
ns = "rb1_base_a"
goto, pick, place = GoToComponent(ns), PickComponent(ns), PlaceComponent(ns)
avail, marker, door = AvailabilityComponent(ns), PoseMarkerComponent(ns), DoorComponent(ns)
for c in (goto, pick, place, avail, marker, door):
    c.register()
    c.register()  # idempotent
out = {}
seen = []
remove = avail.on_availability(lambda m: seen.append(m.operation_state))
raw = []  # the same messages serialized (the rclpy twin's on_<prop>_serialized)
remove_raw = avail.on_availability_serialized(raw.append)

def until_finished(query, mission_id):
    states = []
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        r = query(mission_id=mission_id)
        states.append(r.state.current_state)
        if r.state.current_state == "finished":
            return r, states
        time.sleep(0.05)
    raise SystemExit("never finished")

def wait_for(get, predicate):
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        m = get(timeout=5)
        if predicate(m):
            return m
        time.sleep(0.05)
    raise SystemExit("condition never met")

goal = {"header": {"frame_id": "map", "stamp": {"secs": 1, "nsecs": 2}}, "pose": {"x": 1.5, "y": 3.0, "theta": 0.5}}
started = goto.call_gotoRun(goto.construct_gotoRun_Msg(procedure={"goals": [goal]}))
out["goto_started"] = [started.mission_id, started.response.state.current_state, started.response.result.result]
out["moving"] = wait_for(avail.get_availability_value, lambda m: m.operation_state == "moving").operation_state
try:
    goto.call_gotoRun()
except CallFailed as e:
    out["busy"] = [e.service, e.message, e.response.state.current_state]
r, states = until_finished(goto.call_gotoQuery, started.mission_id)
out["goto_done"] = [r.state.header.id, r.state.last_event, r.result.message, sorted(set(states))]
status = wait_for(avail.get_value, lambda m: m.operation_state == "idle")
out["pose"] = [status.localization_status.pose.pose.x, status.localization_status.pose.pose.y]
out["markers"] = [m.id for m in wait_for(marker.get_value, lambda m: len(m.markers) > 0).markers]
# rospy publishes through a queue thread: a message published just before the process exits can be lost, so
# the door command goes out here, long after register() connected it and well before the client ends
door.publish_door_Msg(door.construct_door_Msg(data=1.0))

started = pick.call_pickRun(pick.construct_pickRun_Msg(procedure={"pick_frame_id": "rb1_base_b_cart3_contact"}))
r, _ = until_finished(pick.call_pickQuery, started.mission_id)
out["pick_done"] = [started.mission_id, r.state.header.id, r.state.last_event]
lifted = wait_for(avail.get_value, lambda m: m.robot_status.elevator.position == "up")
out["elevator"] = lifted.robot_status.elevator.position

started = place.call_placeRun(place.construct_placeRun_Msg())
r, _ = until_finished(place.call_placeQuery, None)  # default: the mission this object started
out["place_done"] = [started.mission_id, r.state.header.id, r.state.last_event]

started = goto.call_gotoRun(goto.construct_gotoRun_Msg(procedure={"goals": [goal]}))
cancelled = goto.call_gotoCancel()  # default: the mission just started
after = goto.call_gotoQuery(mission_id=started.mission_id)
out["cancel"] = [started.mission_id, cancelled.state.header.id, cancelled.state.current_state,
                 cancelled.state.last_event, after.state.last_event]

remove()
remove_raw()
from robot_local_control_msgs.msg import Status
out["callback_seen"] = len(seen) > 0 and "moving" in seen
states = [Status().deserialize(d).operation_state for d in raw]
out["serialized_seen"] = len(raw) > 0 and states[: len(seen)] == seen[: len(raw)]
emit(out)
"""


def test_scenario_against_the_simulated_robot(master: Master, path: list[Path], interfaces: Path) -> None:
    with harness.run_sim(master, interfaces, "rb1_base_a", "--duration", "0.4", "--rate", "20") as sim:
        out = harness.run_client(master, path, SCENARIO)
        assert sim.read_until("door", 5.0) == "door 1.0"
    goto_id = out["goto_started"][0]
    assert out["goto_started"] == [goto_id, "queued", "ok"]
    assert out["moving"] == "moving"
    assert out["busy"][0] == "/rb1_base_a/robot_local_control/NavigationComponent/GoToComponent/add"
    assert out["busy"][1] == (
        'Could not add procedure to "GoToComponent" because component: "GoToComponent" is already running a procedure'
    )
    assert out["busy"][2] == "unknown"
    assert out["goto_done"][:3] == [goto_id, "finish", "Perfect"]
    assert "finished" in out["goto_done"][3]
    assert out["pose"] == [1.5, 3.0]
    assert out["markers"] == [3]
    pick_id = out["pick_done"][0]
    assert out["pick_done"] == [pick_id, pick_id, "finish"] and pick_id > goto_id
    assert out["elevator"] == "up"
    place_id = out["place_done"][0]
    assert out["place_done"] == [place_id, place_id, "finish"]
    cancel_id = out["cancel"][0]
    assert out["cancel"] == [cancel_id, cancel_id, "finished", "cancel", "cancel"]
    assert out["callback_seen"] is True
    assert out["serialized_seen"] is True


READY = """
from robotnik_rb_1_adaptor import *
emit([GoToComponent("ready_a").servers_ready(), GoToComponent("nobody_here").servers_ready()])
"""


def test_servers_ready_says_which_services_the_master_knows(master: Master, path: list[Path], interfaces: Path) -> None:
    """`servers_ready()`: the robot's services there while its node runs, gone once it stopped; another robot's
    never there (the edge node's presence reads it)."""
    with harness.run_sim(master, interfaces, "ready_a"):
        there, nobody = harness.run_client(master, path, READY)
    gone, _ = harness.run_client(master, path, READY)
    names = {"gotoRun", "gotoQuery", "gotoCancel"}
    assert set(there) >= names and all(there.values()), there
    assert set(nobody) == set(there) and not any(nobody.values()), nobody
    assert set(gone) == set(there) and not any(gone.values()), gone


NO_ROBOT = """
from robotnik_rb_1_adaptor import *
c = GoToComponent("nobody_here", wait_timeout=0.5)
t = time.monotonic()
try:
    c.call_gotoQuery()
    emit("no error")
except ServiceUnavailable as e:
    emit([type(e).__name__, e.service, time.monotonic() - t])
"""


def test_no_robot_raises_service_unavailable_within_the_timeout(master: Master, path: list[Path]) -> None:
    name, service, elapsed = harness.run_client(master, path, NO_ROBOT)
    assert (name, service) == (
        "ServiceUnavailable",
        "/nobody_here/robot_local_control/NavigationComponent/GoToComponent/query_state",
    )
    assert 0.4 <= elapsed < 1.5


NO_ROBOT_WITHIN_THE_TIMEOUT = """
from robotnik_rb_1_adaptor import *
c = GoToComponent("nobody_here", timeout=0.5, wait_timeout=5.0)
try:
    c.call_gotoQuery()
    emit("no error")
except ServiceUnavailable as e:
    emit(str(e))
"""


def test_a_wait_for_a_service_cut_short_by_the_call_timeout_says_how_long_in_plain_numbers(
    master: Master, path: list[Path]
) -> None:
    """The edge node relays this message to the application ("the robot is not reachable: ..."): it said
    "waited 9.99999 s" for a call timeout of 10 s (the time left of the call, printed in full)."""
    message = harness.run_client(master, path, NO_ROBOT_WITHIN_THE_TIMEOUT)
    assert message.endswith("is not available (waited 0.5 s)"), message


HANG = """
from robotnik_rb_1_adaptor import *
c = GoToComponent("hang", timeout=0.5)
out = [c.call_gotoQuery(mission_id=7, timeout=30).state.header.id]   # answered: the connection is now persistent
for _ in range(2):   # on the persistent connection, then on a fresh one
    t = time.monotonic()
    try:
        c.call_gotoQuery(mission_id=8)
        out.append("answered")
    except CallTimeout as e:
        out.append([type(e).__name__, e.service, e.timeout, time.monotonic() - t])
emit(out)
"""


def test_server_that_never_answers_raises_call_timeout(master: Master, path: list[Path], interfaces: Path) -> None:
    name = "/hang/robot_local_control/NavigationComponent/GoToComponent/query_state"
    with harness.run_server(master, interfaces, "hang_server.py", name, "1"):
        out = harness.run_client(master, path, HANG)
    assert out[0] == 7
    for attempt in out[1:]:
        assert attempt[:3] == ["CallTimeout", name, 0.5]
        assert 0.45 <= attempt[3] < 5.0  # the 0.5 s applied (a loaded machine may add a few seconds), not a hang


NO_MESSAGE = """
from robotnik_rb_1_adaptor import *
c = AvailabilityComponent("silent_robot")
t = time.monotonic()
try:
    c.get_availability_value(timeout=0.3)
    emit("got one")
except NoMessage as e:
    emit([type(e).__name__, e.topic, time.monotonic() - t, isinstance(e, AdaptorError)])
"""


def test_nothing_published_raises_no_message_after_the_timeout(master: Master, path: list[Path]) -> None:
    name, topic, elapsed, is_adaptor_error = harness.run_client(master, path, NO_MESSAGE)
    assert (name, topic, is_adaptor_error) == ("NoMessage", "/silent_robot/robot_local_control/state", True)
    assert 0.29 <= elapsed < 1.2


RESTART = """
import sys
from robotnik_rb_1_adaptor import *
c = PickComponent("rb1_restart", timeout=2, wait_timeout=3)

def query():
    try:
        return ["answered", c.call_pickQuery().result.result]
    except AdaptorError as e:
        return [type(e).__name__, str(e)]

emit(query())
sys.stdin.readline()   # the test restarts the robot meanwhile
emit(query())
"""


def test_a_restarted_robot_is_reconnected(master: Master, path: list[Path], interfaces: Path) -> None:
    """The persistent connection dies with the robot; the next call notices and connects anew."""
    prelude = (
        "import json, time, rospy\n"
        "rospy.init_node('restart_client', anonymous=True, disable_signals=True)\n"
        "def emit(v):\n    print(json.dumps(v), flush=True)\n"
    )
    proc = subprocess.Popen(
        [harness.SYSTEM_PYTHON, "-c", prelude + RESTART],
        env=master.env(*path),
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdin is not None and proc.stdout is not None
    expected = [
        "CallFailed",
        "/rb1_restart/robot_local_control/NavigationComponent/PickComponent/query_state failed: "
        "no procedure with id -1",
    ]
    try:
        with harness.run_sim(master, interfaces, "rb1_restart"):
            assert json.loads(proc.stdout.readline()) == expected  # the robot answers: nothing to query
        with harness.run_sim(master, interfaces, "rb1_restart"):
            proc.stdin.write("\n")
            proc.stdin.flush()
            out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert json.loads(out.strip().splitlines()[-1]) == expected
