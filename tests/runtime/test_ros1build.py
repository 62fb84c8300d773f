"""`python -m td2adaptor.support.ros1build`: ROS 1 interface packages, services included, built with Debian's
genpy (msg, srv, and the seven genaction messages of each action) from td2adaptor's own interpreter, which has no
genpy: it runs itself under ROS 1's. Checked for real: every built class's md5 sum is the one td2adaptor computes
(tests/rostypes checks those against Debian's genmsg/genaction), and a rospy service server and client talk
with the built RB-1 service type on a private rosmaster. Every ROS 1 action test builds its modules with it too
(tests/ros1/build_actions.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.rostypes import TypeRegistry
from td2adaptor.rostypes.names import ros1_name
from tests.conftest import EXAMPLE, REPO
from tests.ros1 import harness

NAV_BASE = REPO / "examples" / "nav_base" / "interfaces"
RB1 = EXAMPLE / "interfaces"
NAV2 = REPO / "tests" / "data" / "nav2"

#: every class of the built packages (`pkg.msg` and `pkg.srv` modules): ROS 1 type → md5 sum
_DUMP = """
import importlib, json, sys
out = {}
for package in sys.argv[1:]:
    for kind in ("msg", "srv"):
        try:
            module = importlib.import_module(package + "." + kind)
        except ImportError:
            continue
        for name in dir(module):
            cls = getattr(module, name)
            if isinstance(cls, type) and getattr(cls, "_md5sum", None) and not name.endswith(("Request", "Response")):
                out[cls._type] = cls._md5sum
print(json.dumps(out))
"""


def _build(src: Path, cache: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "td2adaptor.support.ros1build", str(src), str(cache)],
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.parametrize("src", [RB1, NAV_BASE], ids=["rb1 (services)", "nav_base (actions)"])
def test_built_types_have_the_md5_sums_td2adaptor_computes(ros1: None, tmp_path: Path, src: Path) -> None:
    assert subprocess.run([sys.executable, "-c", "import genpy"], capture_output=True).returncode != 0  # a re-run
    built = _build(src, tmp_path / "cache")
    assert built.returncode == 0, built.stderr
    modules = Path(built.stdout.strip())
    assert modules.parent == (tmp_path / "cache").resolve() and (modules / ".complete").is_file()
    packages = sorted(p.name for p in modules.iterdir() if p.is_dir())
    dumped = subprocess.run(
        [harness.SYSTEM_PYTHON, "-c", _DUMP, *packages],
        env=harness.ros_env("http://127.0.0.1:1/", tmp_path, modules),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert dumped.returncode == 0, dumped.stderr
    found: dict[str, str] = json.loads(dumped.stdout)
    diags = Diagnostics()
    reg = TypeRegistry("ros1", [src], diags)
    assert not diags.has_errors
    expected = {}
    for name in reg.known_names():
        if name.split("/")[0] not in packages:
            continue
        parts = [f"{name}_{p}" for p in ("Goal", "Result", "Feedback")] if "/action/" in name else [name]
        expected.update((ros1_name(part), reg.ros1_definition(part)[1]) for part in parts)
    assert found == expected
    services = [n for n in expected if f"{n.split('/')[0]}/srv/{n.split('/')[1]}" in reg.known_names("srv")]
    assert services if src == RB1 else not services
    again = _build(src, tmp_path / "cache")  # cached: the same folder, nothing rebuilt
    assert again.returncode == 0 and again.stdout == built.stdout


def test_a_service_built_with_it_works_on_ros1(ros1: None, tmp_path: Path) -> None:
    """The RB-1's GoToPetition service, served and called with the modules ros1build made."""
    built = _build(RB1, tmp_path / "cache")
    assert built.returncode == 0, built.stderr
    modules = Path(built.stdout.strip())
    server_code = (
        "import rospy\n"
        "from robot_local_control_msgs.srv import GoToPetition, GoToPetitionResponse\n"
        "rospy.init_node('goto_server')\n"
        "def handle(request):\n"
        "    response = GoToPetitionResponse()\n"
        "    response.state.header.id = len(request.procedure.goals) + 41\n"
        "    response.state.current_state = 'queued'\n"
        "    return response\n"
        "rospy.Service('/rb1/goto', GoToPetition, handle)\n"
        "print('ready', flush=True)\n"
        "rospy.spin()\n"
    )
    with harness.rosmaster(tmp_path / "ros") as master:
        server = subprocess.Popen(
            [harness.SYSTEM_PYTHON, "-c", server_code],
            env=master.env(modules),
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
        )
        try:
            harness.Sim(server, []).read_until("ready", 30.0)
            answer = harness.run_client(
                master,
                [modules],
                "from robot_local_control_msgs.srv import GoToPetition, GoToPetitionRequest\n"
                "from robot_local_control_msgs.msg import Pose2DStamped\n"
                "rospy.wait_for_service('/rb1/goto', timeout=20)\n"
                "request = GoToPetitionRequest()\n"
                "request.procedure.goals = [Pose2DStamped()]\n"
                "response = rospy.ServiceProxy('/rb1/goto', GoToPetition)(request)\n"
                "emit([response.state.header.id, response.state.current_state, GoToPetition._md5sum])\n",
            )
        finally:
            server.terminate()
            server.wait(timeout=30)
            assert server.stdout is not None
            server.stdout.close()
    reg = TypeRegistry("ros1", [RB1])
    assert answer == [42, "queued", reg.ros1_definition("robot_local_control_msgs/srv/GoToPetition")[1]]


@pytest.mark.parametrize(
    ("layout", "said"),
    [
        ("missing", "is not a folder"),
        ("empty", "no interface package in"),
        (
            "ros2 only",
            "genpy cannot build nav2_msgs/action/NavigateToPose.action (NavigateToPoseAction): Cannot locate",
        ),
    ],
)
def test_what_it_cannot_build_is_one_line(ros1: None, tmp_path: Path, layout: str, said: str) -> None:
    src = NAV2 if layout == "ros2 only" else tmp_path / "interfaces"
    if layout == "empty":
        src.mkdir()
    proc = _build(src, tmp_path / "cache")
    assert proc.returncode == 1, proc.stdout
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith("ros1build: ") and said in proc.stderr
    if layout == "ros2 only":
        assert "unknown package [builtin_interfaces]" in proc.stderr and "search path" not in proc.stderr
        assert not [p for p in (tmp_path / "cache").iterdir() if not p.name.endswith(".lock")]  # nothing half-built


def test_usage() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "td2adaptor.support.ros1build"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2 and "usage:" in proc.stderr


def test_the_generated_readmes_name_both_builds() -> None:
    """Each generated package's README says how to build the robot's own interfaces without a workspace (the
    commands these tests and tests/runtime/test_ros2build.py run), and that `interfaces` folders hold actions."""
    for backend, module, gives in (
        ("rospy", "ros1build", "prints the folder to put on `PYTHONPATH`"),
        ("rclpy", "ros2build", "prints the install prefix to give `td2adaptor run --prefix`"),
    ):
        readme = " ".join((REPO / "generated" / backend / "robotnik_rb_1_adaptor" / "README.md").read_text().split())
        assert f"`python -m td2adaptor.support.{module} DIR CACHE` (`DIR`: that folder; built once," in readme
        assert gives in readme and "msg, srv" in readme
        assert "(`PKG/msg`, `PKG/srv`, `PKG/action`)" in readme
