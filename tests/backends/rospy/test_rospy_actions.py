"""ROS 1 actions of the generated rospy package against real actionlib servers (Debian's rospy, rosmaster and
actionlib; tests/ros1/fibonacci_server.py): goal → feedback → result, cancel mid-goal, aborted, rejected,
pending, server absent and timeouts. test_msgs/Fibonacci comes from tests/data/actions, built with genpy.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import td2adaptor
from td2adaptor.backends.rospy import generator as backend
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from tests import generated
from tests.backends import goal_scenarios
from tests.conftest import REPO
from tests.ros1 import harness
from tests.ros1.harness import Master

CASE = REPO / "tests" / "golden" / "cases" / "fibo_action"
INTERFACES = REPO / "tests" / "data" / "actions"
PKG = "fibo_bot_adaptor"
NS = "fibo_a"
STEP = 0.05  # seconds between two feedback messages of the server


@pytest.fixture(scope="module")
def package(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The fibo_action golden TD's rospy package (a ROS action and a property), generated; its directory."""
    _, package = generated.generate(
        "rospy", CASE / "td.json", tmp_path_factory.mktemp("rospy-actions"), interfaces=[INTERFACES]
    )
    assert package.name == PKG
    return package


@pytest.fixture(scope="module")
def interfaces(tmp_path_factory: pytest.TempPathFactory, ros1: None) -> Path:
    """genpy modules of tests/data/actions, with the seven ROS 1 messages of each action."""
    out = tmp_path_factory.mktemp("genpy") / "modules"
    built = subprocess.run(
        [harness.SYSTEM_PYTHON, str(harness.HERE / "build_actions.py"), str(INTERFACES), str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert built.returncode == 0, built.stderr
    return out


@pytest.fixture(scope="module")
def server(master: Master, interfaces: Path) -> Iterator[None]:
    with harness.run_server(master, interfaces, "fibonacci_server.py", NS, str(STEP)):
        yield


@pytest.fixture(scope="module")
def path(package: Path, interfaces: Path) -> list[Path]:
    return [interfaces, package / "src"]


#: client code: an ActionGoalClient of the package's runtime for another action server of the robot
RAW_CLIENT = (
    f"from {PKG}._actions import ActionGoalClient\n"
    "from test_msgs.msg import FibonacciAction as A, FibonacciGoal as G, FibonacciResult as R, FibonacciFeedback as F\n"
    "def raw_client(name):\n"
    f"    return ActionGoalClient('/{NS}/' + name, A, G, R, F)\n"
)


def scenario(master: Master, path: list[Path], body: str, robot: str = NS) -> Any:
    """Run `body` with the scenarios of tests.backends.goal_scenarios as `s`, `c` (a MathComponent of `robot`),
    `raw_client` and the package's names; it emits the scenario's data."""
    prelude = f"from {PKG} import *\n{RAW_CLIENT}from tests.backends import goal_scenarios as s\n"
    prelude += f"c = MathComponent({robot!r})\n"
    return harness.run_client(master, [*path, REPO], prelude + body, timeout=240)


def client(master: Master, path: list[Path], body: str) -> Any:
    """Run `body` with `c`, a MathComponent of robot NS, and the package's names imported; it calls emit()."""
    return harness.run_client(master, path, f"from {PKG} import *\nc = MathComponent({NS!r})\n" + body)


def test_generated_package_with_an_action_is_lint_format_and_mypy_strict_clean(package: Path) -> None:
    bindir = Path(sys.executable).parent
    for cmd in (
        [str(bindir / "ruff"), "check", "--no-cache", "."],
        [str(bindir / "ruff"), "format", "--check", "--no-cache", "."],
        [str(bindir / "mypy"), "--config-file", "mypy.ini", "--cache-dir", str(package.parent / ".mypy")],
    ):
        out = subprocess.run(cmd, cwd=package, capture_output=True, text=True)
        assert out.returncode == 0, f"{' '.join(cmd[:2])}:\n{out.stdout}\n{out.stderr}"


def test_generated_package_with_an_action_is_pyright_strict_clean(package: Path, tmp_path: Path) -> None:
    from tests.backends.test_python_runtime import STRICT, _pyright

    copy = tmp_path / PKG
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns(".mypy"))
    _pyright({**STRICT, "include": [f"{PKG}/src"], "stubPath": f"{PKG}/stubs"}, tmp_path, sys.executable)


def test_ros1_action_messages_as_topic_types(tmp_path: Path) -> None:
    """genaction's messages are ROS 1 messages: a property may observe an action's feedback topic with them."""
    td = json.loads((CASE / "td.json").read_text(encoding="utf-8"))
    form = td["properties"]["chatter"]["forms"][0]
    form["rosv:name"] = "/{{robotName}}/fibonacci/feedback"
    form["rosv:type"] = "test_msgs/FibonacciActionFeedback"
    (tmp_path / "td.json").write_text(json.dumps(td), encoding="utf-8")
    result = td2adaptor.compile(tmp_path / "td.json", interfaces=[INTERFACES])
    assert result.model is not None, [d.message for d in result.diagnostics]
    assert "ROS424" in [d.code for d in result.diagnostics]  # ROS 2 has no such message
    tree = backend.generate(result.model, GenOptions(), Diagnostics())
    for rel, data in tree:
        (tmp_path / "out" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "out" / rel).write_bytes(data)
    stub = (tmp_path / "out" / PKG / "stubs" / "test_msgs" / "msg" / "__init__.pyi").read_text()
    assert "class FibonacciActionFeedback(genpy.Message):" in stub
    assert "    status: actionlib_msgs.msg.GoalStatus\n    feedback: FibonacciFeedback\n" in stub
    bindir = Path(sys.executable).parent
    out = subprocess.run(
        [str(bindir / "mypy"), "--config-file", "mypy.ini", "--cache-dir", str(tmp_path / ".mypy")],
        cwd=tmp_path / "out" / PKG,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stdout


def test_action_stubs_catch_type_errors(package: Path, tmp_path: Path) -> None:
    """The GoalHandle is typed from the .action file: a wrong goal or a wrong use of the result is a mypy error."""
    misuse = package / "src" / PKG / "misuse.py"
    misuse.write_text(
        f"from {PKG} import MathComponent\n"
        "from test_msgs.msg import FibonacciResult\n\n"
        "def f(c: MathComponent) -> str:\n"
        "    return c.send_fibonacci(FibonacciResult()).result().sequence\n\n"
        "def g(c: MathComponent) -> None:\n"
        "    c.construct_fibonacci_Goal(order='5')\n"
    )
    try:
        bindir = Path(sys.executable).parent
        out = subprocess.run(
            [str(bindir / "mypy"), "--config-file", "mypy.ini", "--cache-dir", str(tmp_path / ".mypy")],
            cwd=package,
            capture_output=True,
            text=True,
        )
    finally:
        misuse.unlink()
    assert out.returncode == 1, out.stdout
    assert 'Argument 1 to "send_fibonacci" of "MathComponent" has incompatible type "FibonacciResult"' in out.stdout
    assert 'Incompatible return value type (got "Sequence[int]", expected "str")' in out.stdout
    assert 'Argument "order" to "construct_fibonacci_Goal" of "MathComponent" has incompatible type' in out.stdout


def test_goal_feedback_result(master: Master, path: list[Path], server: None) -> None:
    out = client(
        master,
        path,
        "seen = []\n"
        "goal = c.send_fibonacci(c.construct_fibonacci_Goal(order=6))\n"
        "goal.on_feedback(lambda fb: seen.append(list(fb.sequence)))\n"
        "iterated = [list(fb.sequence) for fb in goal.feedback(timeout=10)]\n"
        "result = goal.result(timeout=10)\n"
        "emit({'id': goal.goal_id, 'iterated': iterated, 'seen': seen, 'result': list(result.sequence),\n"
        "      'status': goal.status, 'done': goal.done, 'cancel': goal.cancel()})\n",
    )
    expected = [[0, 1, 1, 2, 3, 5][: i + 1] for i in range(6)]
    assert out["iterated"] == expected  # every feedback message, in order, from the first one on
    assert out["seen"] == expected[len(expected) - len(out["seen"]) :]  # the callback: from when it was added
    assert out["result"] == [0, 1, 1, 2, 3, 5]
    assert out["id"] and isinstance(out["id"], str)
    assert (out["status"], out["done"], out["cancel"]) == ("succeeded", True, False)


def test_feedback_published_right_before_the_result_is_kept(master: Master, path: list[Path], server: None) -> None:
    """The hasty server publishes its last feedback message and the result back to back; they travel on two
    connections, so the result often arrives first. actionlib's own client drops feedback after the result;
    the goal handle keeps every message, in order (callbacks and the iterator's buffer)."""
    out = client(
        master,
        path,
        f"{RAW_CLIENT}import time\n"
        "hasty = raw_client('hasty')\n"
        "runs = []\n"
        "for n in range(1, 16):\n"
        "    goal = hasty.send(G(order=n), 10.0, 10.0)\n"
        "    goal.result(10.0)\n"
        "    deadline = time.monotonic() + 5\n"
        "    while len(seen := [list(fb.sequence) for fb in goal.feedback(timeout=1)]) < n:\n"
        "        if time.monotonic() > deadline:\n"
        "            break\n"
        "        time.sleep(0.02)\n"
        "    runs.append(seen)\n"
        "emit(runs)\n",
    )
    sequence = [0, 1, 1, 2, 3, 5, 8, 13, 21, 34, 55, 89, 144, 233, 377]
    assert out == [[sequence[: i + 1] for i in range(n)] for n in range(1, 16)]


def test_cancel_mid_goal(master: Master, path: list[Path], server: None) -> None:
    out = client(
        master,
        path,
        "goal = c.send_fibonacci(c.construct_fibonacci_Goal(order=1000))\n"
        "first = next(goal.feedback(timeout=10))\n"
        "accepted = goal.cancel(timeout=10)\n"
        "try:\n"
        "    goal.result(timeout=10)\n"
        "    emit('succeeded?')\n"
        "except GoalCanceled as e:\n"
        "    emit({'first': list(first.sequence), 'accepted': accepted, 'status': goal.status, 'reason': e.reason,\n"
        "          'partial': len(e.response.sequence), 'is_call_failed': isinstance(e, CallFailed)})\n",
    )
    assert out["first"] == [0] and out["accepted"] is True and out["status"] == "canceled"
    assert out["reason"].startswith("canceled at step ") and 1 <= out["partial"] < 1000
    assert out["is_call_failed"]


def test_first_goal_waits_until_the_server_publishes_to_us(master: Master, interfaces: Path, path: list[Path]) -> None:
    """A ROS 1 publisher answers a new subscriber's handshake before it adds it to the subscribers it sends to;
    a goal sent in between lost its first feedback messages (a clean-clone CI run under load got [0, 1] as the
    first feedback) or even its result. The server here takes our subscriptions up 1.5 s late: the first goal
    still gets every feedback message and its result."""
    with harness.run_server(master, interfaces, "fibonacci_server.py", "fibo_slow", str(STEP), "1.5"):
        out = harness.run_client(
            master,
            path,
            f"from {PKG} import *\nc = MathComponent('fibo_slow')\n"
            "goal = c.send_fibonacci(c.construct_fibonacci_Goal(order=4))\n"
            "iterated = [list(fb.sequence) for fb in goal.feedback(timeout=10)]\n"
            "emit({'iterated': iterated, 'result': list(goal.result(timeout=10).sequence)})\n",
        )
    assert out == {"iterated": [[0], [0, 1], [0, 1, 1], [0, 1, 1, 2]], "result": [0, 1, 1, 2]}


def test_a_rejection_whose_status_comes_before_its_result_is_a_rejection(
    master: Master, path: list[Path], server: None
) -> None:
    """The tardy server rejects like picky but sends its results 0.5 s late: the status REJECTED arrives while
    the result is still on its way. send must still raise GoalRejected with the server's words (it took the
    terminal status as the goal being taken up and returned a handle: the clean-clone CI's 'client printed
    nothing' under load)."""
    out = client(
        master,
        path,
        f"{RAW_CLIENT}tardy = raw_client('tardy')\n"
        "try:\n"
        "    tardy.send(G(order=-1), 10.0, 10.0)\n"
        "    emit({'raised': None})\n"
        "except GoalRejected as e:\n"
        "    emit({'raised': type(e).__name__, 'reason': e.reason})\n",
    )
    assert out == {"raised": "GoalRejected", "reason": "order must not be negative"}


def test_aborted_goal(master: Master, path: list[Path], server: None) -> None:
    out = client(
        master,
        path,
        "goal = c.send_fibonacci(c.construct_fibonacci_Goal(order=13))\n"
        "try:\n"
        "    goal.result(timeout=20)\n"
        "except GoalAborted as e:\n"
        "    emit({'reason': e.reason, 'message': str(e), 'status': goal.status, 'n': len(e.response.sequence)})\n",
    )
    assert out == {
        "reason": "13 is unlucky",
        "message": f"/{NS}/fibonacci failed: the goal was aborted: 13 is unlucky",
        "status": "aborted",
        "n": 13,
    }


def test_rejected_goal(master: Master, path: list[Path], server: None) -> None:
    """The picky server (an actionlib ActionServer) rejects a negative order; send raises GoalRejected."""
    out = client(
        master,
        path,
        f"{RAW_CLIENT}picky = raw_client('picky')\n"
        "fine = picky.send(G(order=3), 10.0, 10.0).result(10.0)\n"
        "try:\n"
        "    picky.send(G(order=-1), 10.0, 10.0)\n"
        "except GoalRejected as e:\n"
        "    emit({'fine': list(fine.sequence), 'reason': e.reason, 'message': str(e)})\n",
    )
    assert out == {
        "fine": [0],
        "reason": "order must not be negative",
        "message": f"/{NS}/picky failed: the goal was rejected: order must not be negative",
    }


def test_pending_goal_and_timeouts(master: Master, path: list[Path], server: None) -> None:
    """A server that leaves the goal pending: send returns it as such; result and feedback end at their timeout."""
    out = client(
        master,
        path,
        f"{RAW_CLIENT}stuck = raw_client('stuck')\n"
        "goal = stuck.send(G(order=3), 3.0, 10.0)\n"
        "errors = []\n"
        "for wait in (lambda: goal.result(timeout=0.3), lambda: next(goal.feedback(timeout=0.3))):\n"
        "    try:\n"
        "        wait()\n"
        "    except CallTimeout as e:\n"
        "        errors.append(str(e))\n"
        "emit({'status': goal.status, 'done': goal.done, 'errors': errors})\n",
    )
    assert out == {
        "status": "pending",
        "done": False,
        "errors": ["no response from /fibo_a/stuck within 0.3 s"] * 2,
    }


def test_result_timeout_leaves_the_goal_running(master: Master, path: list[Path], server: None) -> None:
    out = client(
        master,
        path,
        "goal = c.send_fibonacci(c.construct_fibonacci_Goal(order=1000))\n"
        "try:\n"
        "    goal.result(timeout=0.2)\n"
        "except CallTimeout as e:\n"
        "    timed_out = str(e)\n"
        "running = goal.status\n"
        "goal.cancel()\n"
        "try:\n"
        "    goal.result()\n"
        "except GoalCanceled:\n"
        "    emit({'timed_out': timed_out, 'running': running, 'status': goal.status})\n",
    )
    assert out == {
        "timed_out": f"no response from /{NS}/fibonacci within 0.2 s",
        "running": "executing",
        "status": "canceled",
    }


def test_server_killed_mid_goal(master: Master, interfaces: Path, path: list[Path]) -> None:
    """The robot dies during a goal: waits end with ServiceUnavailable once its connections drop, not at their
    (long) timeout."""
    with harness.run_server(master, interfaces, "fibonacci_server.py", "fibo_doomed", str(STEP)) as doomed:
        out = harness.run_client(
            master,
            path,
            "import os, signal\n"
            f"from {PKG} import *\n"
            "c = MathComponent('fibo_doomed')\n"
            "goal = c.send_fibonacci(c.construct_fibonacci_Goal(order=1000))\n"
            "next(goal.feedback(timeout=10))\n"
            f"os.kill({doomed.pid}, signal.SIGKILL)\n"
            "errors = []\n"
            "start = time.monotonic()\n"
            "for wait in (lambda: goal.result(timeout=60), lambda: list(goal.feedback(timeout=60))):\n"
            "    try:\n"
            "        wait()\n"
            "    except ServiceUnavailable as e:\n"
            "        errors.append(str(e))\n"
            "emit({'errors': errors, 'early': time.monotonic() - start < 30, 'done': goal.done})\n",
        )
    assert out == {
        "errors": ["action /fibo_doomed/fibonacci is not available (the action server went away during the goal)"] * 2,
        "early": True,
        "done": False,
    }


def test_server_absent(master: Master, path: list[Path]) -> None:
    out = harness.run_client(
        master,
        path,
        f"from {PKG} import *\n"
        "c = MathComponent('nobody_here', wait_timeout=0.5)\n"
        "try:\n"
        "    c.send_fibonacci(timeout=1.0)\n"
        "except ServiceUnavailable as e:\n"
        "    emit(str(e))\n",
    )
    assert out == "action /nobody_here/fibonacci is not available (no action server within 0.5 s)"


def test_servers_ready_says_whether_the_action_server_is_there(
    master: Master, interfaces: Path, path: list[Path]
) -> None:
    """`servers_ready()`: the action server of a robot whose server runs is there, another robot's is not."""
    code = f"from {PKG} import *\nemit([MathComponent(r).servers_ready() for r in ('fibo_ready', 'nobody_here')])\n"
    with harness.run_server(master, interfaces, "fibonacci_server.py", "fibo_ready", str(STEP)):
        out = harness.run_client(master, path, code)
    assert out == [{"fibonacci": True}, {"fibonacci": False}]


def test_invalid_goal_and_uninitialised_node(master: Master, path: list[Path]) -> None:
    out = client(
        master,
        path,
        "from test_msgs.msg import FibonacciResult\n"
        "try:\n"
        "    c.send_fibonacci(FibonacciResult())\n"
        "except InvalidMessage as e:\n"
        "    emit(str(e))\n",
    )
    assert out == f"/{NS}/fibonacci: expected test_msgs/FibonacciGoal, not FibonacciResult"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(map(str, path)))
    code = f"from {PKG} import *\ntry:\n    MathComponent().send_fibonacci()\nexcept NotInitialized:\n    print('ok')\n"
    done = subprocess.run([harness.SYSTEM_PYTHON, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == "ok", done.stderr


# -- the callback API (start_X): the scenarios of tests.backends.goal_scenarios, the same as on ROS 2


def test_a_burst_of_1000_feedback_messages_is_told_once_each_in_order_then_one_end(
    master: Master, path: list[Path], server: None
) -> None:
    """The burst server publishes 1,000 feedback messages back to back, then the result (on another
    connection: it often arrives first). on_feedback gets each once, in order, between on_accepted and
    exactly one on_done; the blocking iterator reads the same buffer. A lost or repeated message fails
    check_burst (goal_scenarios)."""
    out = scenario(
        master,
        path,
        "burst = raw_client('burst')\nemit(s.burst(lambda **cb: burst.start(G(order=1000), 10.0, 10.0, **cb)))\n",
    )
    goal_scenarios.check_burst(out, 1000)


def test_cancel_through_the_callback_api(master: Master, path: list[Path], server: None) -> None:
    out = scenario(
        master, path, "emit(s.cancel(lambda **cb: c.start_fibonacci(c.construct_fibonacci_Goal(order=1000), **cb)))\n"
    )
    goal_scenarios.check_cancel(out)


def test_a_killed_server_ends_the_goal_through_on_done_with_no_thread_waiting_on_it(
    master: Master, interfaces: Path, path: list[Path]
) -> None:
    """SIGKILL to the action server mid-goal: the adaptor's goals thread (one per process, not one per goal)
    sees its connections drop and ends the goal lost through on_done."""
    with harness.run_server(master, interfaces, "fibonacci_server.py", "fibo_doomed_cb", str(STEP)) as doomed:
        out = scenario(
            master,
            path,
            "import os, signal\n"
            f"kill = lambda: os.kill({doomed.pid}, signal.SIGKILL)\n"
            "long = lambda **cb: c.start_fibonacci(c.construct_fibonacci_Goal(order=1000), **cb)\n"
            "short = lambda **cb: c.start_fibonacci(c.construct_fibonacci_Goal(order=1), **cb)\n"
            "emit(s.killed(long, kill, short))\n",
            robot="fibo_doomed_cb",
        )
    goal_scenarios.check_killed(out, bound=10.0)


def test_50_concurrent_goals_start_no_thread(master: Master, path: list[Path], server: None) -> None:
    out = scenario(
        master,
        path,
        "hasty = raw_client('hasty')\nemit(s.concurrent(lambda **cb: hasty.start(G(order=5), 10.0, 10.0, **cb), 50))\n",
    )
    sequence = [0, 1, 1, 2, 3]
    goal_scenarios.check_concurrent(out, [sequence[: i + 1] for i in range(5)], sequence)


def test_rejoin_of_a_goal_the_server_does_not_know_tells_no_acceptance_and_the_plain_words(
    master: Master, path: list[Path], server: None
) -> None:
    """`rejoin_X` (issue 32, found by a new user's trial on ROS 1): an id the server does not list ends lost with
    no `on_accepted` and no status told first (before: accepted, then `executing`, then lost), and its reason is
    the plain words, as on ROS 2 (before: empty, so the edge node said "... following it on failed: /ns/action
    failed: the action server does not know goal ...")."""
    out = client(
        master,
        path,
        "import threading\n"
        "told = []\n"
        "ended = threading.Event()\n"
        "h = c.rejoin_fibonacci('/nobody-1-2.000', on_accepted=lambda: told.append('accepted'),\n"
        "    on_status=lambda status: told.append('status ' + status),\n"
        "    on_done=lambda o: (told.append(o.status), told.append(o.reason), ended.set()))\n"
        "ended.wait(60)\n"
        "emit({'told': told, 'result': repr(h.outcome.result)})\n",
    )
    assert out["told"] == ["lost", "the action server does not know goal /nobody-1-2.000"], out
    assert out["result"] == "None", out  # a lost goal has no result (not a default one of zeros)
