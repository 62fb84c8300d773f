"""ROS 2 actions in the generated rclpy adaptor, against real ROS 2 Jazzy: no mocks.

The adaptor is generated from tests.lowering.test_actions.action_td (test_msgs/action/Fibonacci, whose Python
types come from the `ros-jazzy-test-msgs` wheel) and imported from its source. The action server is a real
`rclpy.action.ActionServer` on a node of this process, spun by its own multi-threaded executor, so that it
executes goals while it answers cancel requests. What the server does depends on the goal's `order`:
negative → rejected; 77 → aborted after two feedback messages; 55 → no feedback for `SILENT_FOR` seconds, then
succeeded; `BURST + n` → n feedback messages `[i]` back to back (its feedback publisher keeps 2,000), then `[n]`
as the result; otherwise one feedback message per step (`STEP` seconds apart) and the sequence as the result,
ending canceled when a cancel was requested. A server killed mid-goal is tests.runtime.fibo_ros2 in a process
of its own.
"""

from __future__ import annotations

import importlib
import json
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tests.backends import goal_scenarios
from tests.backends.rclpy.test_rclpy_ros2 import run_in_executor
from tests.lowering.test_actions import INTERFACES, action_td
from tests.ros2 import env
from tests.ros2.common import Process, require_ros2

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, ros_node

ROBOT = "fibo_robot"
STEP = 0.05
ABORT = 77
SILENT, SILENT_FOR = 55, 2.0
BURST = 20000


def _sequence(order: int) -> list[int]:
    seq = [0, 1]
    while len(seq) < order + 1:
        seq.append(seq[-1] + seq[-2])
    return seq[: order + 1]


@pytest.fixture(scope="session")
def fibo_adaptor(ros2_domain: int, tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    require_ros2()
    import td2adaptor
    from td2adaptor.backends.registry import load as load_backend
    from td2adaptor.diagnostics import Diagnostics, Severity
    from td2adaptor.generation.backend import GenOptions

    base = tmp_path_factory.mktemp("fibo")
    td = base / "td.json"
    td.write_text(json.dumps(action_td()), encoding="utf-8")
    result = td2adaptor.compile(td, interfaces=[INTERFACES])
    assert result.model is not None, [d.message for d in result.diagnostics]
    diags = Diagnostics()
    tree = load_backend("rclpy").generate(result.model, GenOptions(), diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    for rel, data in tree:
        path = base / "src" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    src = base / "src" / result.model.package_name
    sys.path.insert(0, str(src))
    return importlib.import_module(result.model.package_name)


class FiboServer:
    """The action server (see the module docstring); `goals` counts the goals it executed."""

    def __init__(self, context: Any, name: str) -> None:
        import rclpy
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.qos import QoSProfile
        from test_msgs.action import Fibonacci

        self.node: Any = rclpy.create_node("fibo_server", context=context)
        self.goals = 0
        self.canceled = threading.Event()
        self.stopping = threading.Event()  # goals still executing end at once: the executor can shut down

        def on_goal(goal: Any) -> Any:
            return GoalResponse.REJECT if goal.order < 0 else GoalResponse.ACCEPT

        def execute(handle: Any) -> Any:
            self.goals += 1
            order = handle.request.order
            result = Fibonacci.Result()
            if order >= BURST:
                for i in range(1, order - BURST + 1):
                    feedback = Fibonacci.Feedback()
                    feedback.sequence = [i]
                    handle.publish_feedback(feedback)
                handle.succeed()
                result.sequence = [order - BURST]
                return result
            if order == SILENT:
                self.stopping.wait(SILENT_FOR)
                handle.succeed()
                result.sequence = _sequence(1)
                return result
            for i in range(1, order + 1):
                if self.stopping.is_set():
                    handle.abort()
                    return result
                if handle.is_cancel_requested:
                    handle.canceled()
                    self.canceled.set()
                    result.sequence = _sequence(i - 1)
                    return result
                feedback = Fibonacci.Feedback()
                feedback.sequence = _sequence(i)
                handle.publish_feedback(feedback)
                if order == ABORT and i == 2:
                    handle.abort()
                    result.sequence = _sequence(i)
                    return result
                time.sleep(STEP)
            handle.succeed()
            result.sequence = _sequence(order)
            return result

        self.server = ActionServer(
            self.node,
            Fibonacci,
            name,
            execute_callback=execute,
            goal_callback=on_goal,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
            callback_group=ReentrantCallbackGroup(),
            feedback_pub_qos_profile=QoSProfile(depth=2000),  # a burst is not overwritten before it is sent
        )
        self.executor = MultiThreadedExecutor(num_threads=4, context=context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def stop(self) -> None:
        self.stopping.set()  # else a goal left running (order 200) could outlast the shutdown's wait, and
        # destroying the node under the spinning executor raises InvalidHandle in its thread
        self.executor.shutdown(timeout_sec=5)
        self.thread.join(5)
        self.server.destroy()
        self.node.destroy_node()


@pytest.fixture(scope="module")
def fibo_server(ros_node: Any) -> Iterator[FiboServer]:
    server = FiboServer(ros_node.context, f"/{ROBOT}/fibonacci")
    try:
        yield server
    finally:
        server.stop()


@pytest.fixture
def fibo(fibo_adaptor: ModuleType, ros_node: Any, fibo_server: FiboServer) -> Any:
    return fibo_adaptor.MathComponent(ros_node, ROBOT, timeout=10.0, wait_timeout=15.0)


def test_goal_accepted_feedback_by_callback_and_iterator_then_result(fibo_adaptor: ModuleType, fibo: Any) -> None:
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=6))
    assert isinstance(handle, fibo_adaptor.GoalHandle)
    assert len(handle.goal_id) == 32 and int(handle.goal_id, 16) >= 0
    by_callback: list[list[int]] = []
    remove = handle.on_feedback(lambda fb: by_callback.append(list(fb.sequence)))
    iterated = [list(fb.sequence) for fb in handle.feedback(timeout=5.0)]
    # the iterator sees every feedback message from the first one, in order, and ends with the goal
    assert iterated == [_sequence(i) for i in range(1, 7)]
    result = handle.result(timeout=5.0)
    assert list(result.sequence) == _sequence(6)
    assert handle.status == "succeeded" and handle.done
    assert by_callback and by_callback == iterated[-len(by_callback) :]
    remove()


def test_callback_sees_every_feedback_when_registered_at_once(fibo: Any) -> None:
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=8))
    seen: list[int] = []
    handle.on_feedback(lambda fb: seen.append(len(fb.sequence)))
    handle.result(timeout=5.0)
    assert seen and seen == sorted(seen) and seen[-1] == 9


def test_cancel_mid_goal(fibo_adaptor: ModuleType, fibo: Any, fibo_server: FiboServer) -> None:
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=200))
    first = next(iter(handle.feedback(timeout=5.0)))
    assert list(first.sequence) == _sequence(1)
    assert handle.status == "executing"  # feedback came: executing, whether or not its status message did
    assert handle.cancel(timeout=5.0) is True
    with pytest.raises(fibo_adaptor.GoalCanceled) as caught:
        handle.result(timeout=5.0)
    assert isinstance(caught.value, fibo_adaptor.CallFailed)
    assert len(caught.value.response.sequence) < 201
    assert handle.status == "canceled"
    assert handle.cancel(timeout=5.0) is False  # already over
    assert fibo_server.canceled.is_set()


def test_goal_rejected(fibo_adaptor: ModuleType, fibo: Any) -> None:
    with pytest.raises(fibo_adaptor.GoalRejected, match="rejected"):
        fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=-1))


def test_goal_aborted(fibo_adaptor: ModuleType, fibo: Any) -> None:
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=ABORT))
    assert len(list(handle.feedback(timeout=5.0))) == 2
    with pytest.raises(fibo_adaptor.GoalAborted) as caught:
        handle.result(timeout=5.0)
    assert list(caught.value.response.sequence) == _sequence(2)
    assert handle.status == "aborted"


def test_timeouts_never_block_forever(fibo_adaptor: ModuleType, fibo: Any) -> None:
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=100))
    start = time.monotonic()
    with pytest.raises(fibo_adaptor.CallTimeout):
        handle.result(timeout=0.3)
    assert time.monotonic() - start < 2.0
    assert not handle.done  # the goal goes on
    items = handle.feedback(timeout=0.001)
    with pytest.raises(fibo_adaptor.CallTimeout):
        for _ in range(1000):  # faster than the server: some wait must time out
            next(items)
            time.sleep(0)
    with pytest.raises(ValueError):
        handle.result(timeout=float("inf"))
    assert handle.cancel(timeout=5.0)
    with pytest.raises(fibo_adaptor.GoalCanceled):
        handle.result(timeout=5.0)


def test_server_absent(fibo_adaptor: ModuleType, ros_node: Any) -> None:
    lonely = fibo_adaptor.MathComponent(ros_node, "no_such_robot", timeout=1.0, wait_timeout=0.5)
    start = time.monotonic()
    with pytest.raises(fibo_adaptor.ServiceUnavailable) as raised:
        lonely.send_fibonacci()
    assert time.monotonic() - start < 3.0
    # an action, said as one (it said "service ... is not available", which the new-user run found misleading)
    assert str(raised.value) == "action /no_such_robot/fibonacci is not available (no action server within 0.5 s)"


def test_a_silent_server_that_answers_its_probes_is_not_taken_as_gone(fibo_adaptor: ModuleType, fibo: Any) -> None:
    """No feedback for several times the handle's server_timeout: the server answers the probes, the goal ends
    as the server says."""
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=SILENT))
    assert handle.server_timeout == fibo_adaptor.runtime.SERVER_TIMEOUT == 2.5
    handle.server_timeout = SILENT_FOR / 4
    assert list(handle.result(timeout=SILENT_FOR + 10.0).sequence) == _sequence(1)
    assert handle.feedback_received == 0 and handle.status == "succeeded"


def test_a_killed_server_ends_every_wait_with_service_unavailable(fibo_adaptor: ModuleType, ros_node: Any) -> None:
    """The action server's process killed (SIGKILL) mid-goal: discovery would tell after the lease (20 s with
    Fast DDS); result(), result_async() and cancel() end with ServiceUnavailable within the handle's
    server_timeout instead of waiting out their timeouts."""
    server = Process(
        [sys.executable, "-m", "tests.runtime.fibo_ros2", "fibo_doomed_a", "fibo_doomed_b"], env.child_env([])
    )
    try:
        server.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        goals = []
        for ns in ("fibo_doomed_a", "fibo_doomed_b"):
            component = fibo_adaptor.MathComponent(ros_node, ns, timeout=10.0, wait_timeout=15.0)
            handle = component.send_fibonacci(component.construct_fibonacci_Goal(order=1000))  # slow, until canceled
            handle.server_timeout = 1.0
            next(handle.feedback(timeout=10.0))
            goals.append(handle)
        sync, coroutine = goals
        server.proc.send_signal(signal.SIGKILL)
        server.proc.wait(10)
        killed = time.monotonic()
        with pytest.raises(fibo_adaptor.ServiceUnavailable, match="^action .*fibonacci is not available .*went away"):
            sync.result(timeout=30.0)
        assert time.monotonic() - killed < 1.0 + 2.0
        assert not sync.done
        with pytest.raises(fibo_adaptor.ServiceUnavailable, match="action server went away"):
            run_in_executor(ros_node, coroutine.result_async(timeout=30.0), timeout=40.0)
        started = time.monotonic()
        for handle in goals:
            with pytest.raises(fibo_adaptor.ServiceUnavailable):
                handle.cancel(timeout=30.0)
            with pytest.raises(fibo_adaptor.ServiceUnavailable):
                list(handle.feedback(timeout=30.0))  # the messages received, then a wait for more
        assert time.monotonic() - started < 2.0  # known gone: at once
    finally:
        server.stop()


def test_blocking_from_a_callback_is_refused(fibo_adaptor: ModuleType, fibo: Any) -> None:
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=5))
    errors: list[BaseException] = []

    def blocking(_fb: Any) -> None:
        try:
            handle.result(timeout=1.0)
        except fibo_adaptor.ExecutorError as exc:
            errors.append(exc)

    handle.on_feedback(blocking)
    handle.result(timeout=5.0)
    assert errors


def test_awaitable_goal_feedback_and_result_in_a_coroutine_callback(fibo_adaptor: ModuleType, fibo: Any) -> None:
    """send_X_async, feedback_async and result_async in a task of the node's single-threaded executor: had any
    of them blocked its thread, no feedback nor result could arrive (the same executor takes them)."""

    async def mission() -> tuple[str, list[list[int]], list[int], str]:
        goal = await fibo.send_fibonacci_async(fibo.construct_fibonacci_Goal(order=5))
        items = [list(fb.sequence) async for fb in goal.feedback_async(timeout=5.0)]
        result = await goal.result_async(timeout=5.0)
        return goal.goal_id, items, list(result.sequence), goal.status

    goal_id, items, result, status = run_in_executor(fibo.node, mission())
    assert len(goal_id) == 32
    assert items == [_sequence(i) for i in range(1, 6)]
    assert result == _sequence(5) and status == "succeeded"


def test_awaitable_cancel_rejection_timeout_and_absent_server(fibo_adaptor: ModuleType, fibo: Any) -> None:
    async def cancel_mid_goal() -> tuple[list[int], bool, int, bool]:
        goal = await fibo.send_fibonacci_async(fibo.construct_fibonacci_Goal(order=200))
        first = await anext(goal.feedback_async(timeout=5.0))
        canceling = await goal.cancel_async(timeout=5.0)
        try:
            await goal.result_async(timeout=5.0)
        except fibo_adaptor.GoalCanceled as exc:
            return list(first.sequence), canceling, len(exc.response.sequence), await goal.cancel_async(timeout=5.0)
        raise AssertionError("the goal was not canceled")

    first, canceling, partial, again = run_in_executor(fibo.node, cancel_mid_goal())
    assert first == _sequence(1) and canceling is True and partial < 201 and again is False

    with pytest.raises(fibo_adaptor.GoalRejected):
        run_in_executor(fibo.node, fibo.send_fibonacci_async(fibo.construct_fibonacci_Goal(order=-1)))

    async def result_too_late() -> tuple[float, bool]:
        goal = await fibo.send_fibonacci_async(fibo.construct_fibonacci_Goal(order=100))
        start = time.monotonic()
        try:
            await goal.result_async(timeout=0.3)
        except fibo_adaptor.CallTimeout:
            waited, done = time.monotonic() - start, goal.done
            await goal.cancel_async(timeout=5.0)
            return waited, done
        raise AssertionError("a goal of 100 steps ended within 0.3 s")

    waited, done = run_in_executor(fibo.node, result_too_late())
    assert 0.25 < waited < 2.0 and not done  # the goal went on until it was canceled

    lonely = fibo_adaptor.MathComponent(fibo.node, "no_such_robot_async", timeout=1.0, wait_timeout=0.5)
    start = time.monotonic()
    with pytest.raises(fibo_adaptor.ServiceUnavailable, match="no_such_robot_async/fibonacci"):
        run_in_executor(fibo.node, lonely.send_fibonacci_async())
    assert time.monotonic() - start < 3.0


def test_generated_action_api_passes_ruff_and_mypy_strict(fibo_adaptor: ModuleType, tmp_path: Path) -> None:
    """The package (runtime, components, stubs of test_msgs/action) and user code against it type-check
    strictly: good use passes, misuse of the goal, the handle and the result is caught."""
    import shutil
    import subprocess

    pkg = Path(fibo_adaptor.__file__ or "").parents[1]
    copy = tmp_path / pkg.name
    shutil.copytree(pkg, copy)
    bin_dir = Path(sys.executable).parent
    for args in (["check", "--no-cache", "."], ["format", "--check", "--no-cache", "."]):
        proc = subprocess.run([str(bin_dir / "ruff"), *args], cwd=copy, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stdout + proc.stderr
    name = fibo_adaptor.__name__
    (copy / "use_ok.py").write_text(
        "from collections.abc import Callable\n"
        "from rclpy.node import Node\n"
        f"from {name} import GoalCanceled, GoalHandle, MathComponent\n"
        "from test_msgs.action import Fibonacci\n\n\n"
        "def run(node: Node) -> list[int]:\n"
        "    fibo = MathComponent(node, 'r', timeout=2.0)\n"
        "    handle: GoalHandle[Fibonacci.Result, Fibonacci.Feedback] = fibo.send_fibonacci(\n"
        "        fibo.construct_fibonacci_Goal(order=5), timeout=1.0\n"
        "    )\n"
        "    remove: Callable[[], None] = handle.on_feedback(lambda fb: print(len(fb.sequence)))\n"
        "    remove()\n"
        "    firsts = [fb.sequence[0] for fb in handle.feedback(timeout=1.0)]\n"
        "    goal_id: str = handle.goal_id\n"
        "    status: str = handle.status\n"
        "    try:\n"
        "        return list(handle.result(timeout=3.0).sequence) + firsts + [len(goal_id + status)]\n"
        "    except GoalCanceled:\n"
        "        return [] if handle.cancel() else [1]\n",
        encoding="utf-8",
    )
    (copy / "use_bad.py").write_text(
        "from rclpy.node import Node\n"
        f"from {name} import MathComponent\n\n\n"
        "def run(node: Node) -> str:\n"
        "    fibo = MathComponent(node)\n"
        "    fibo.construct_fibonacci_Goal(order='five')\n"
        "    fibo.send_fibonacci(fibo.construct_fibonacci_Goal(), 2.0)\n"
        "    return fibo.send_fibonacci().result().sequence\n",
        encoding="utf-8",
    )
    mypy = [str(bin_dir / "mypy"), "--cache-dir", str(tmp_path / "mypy-cache")]
    proc = subprocess.run(mypy, cwd=copy, capture_output=True, text=True)  # setup.cfg: strict, stubs/
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = subprocess.run([*mypy, "use_ok.py", "use_bad.py"], cwd=copy, capture_output=True, text=True)
    lines = [line for line in proc.stdout.splitlines() if ": error:" in line]
    assert all(line.startswith("use_bad.py") for line in lines), proc.stdout
    assert len(lines) == 3, proc.stdout


class ResponseRace:
    """Holds the thread that sends a request inside rclpy's own window: after `ActionClient` sent a request, before it
    recorded the request's sequence number (rclpy 7.1 of Jazzy, ros2/rclpy#1123), until the executor's thread
    has dealt with the response: handled it (rclpy drops a response of no recorded request: "Ignoring unexpected
    goal response", and the request's future never completes) or looked at it ready twice without taking it.

    A loaded machine preempts the caller there by chance (the warehouse demo lost a goal so, once in ten runs);
    here the thread is held until the response is there, every time. Nothing is mocked: rclpy's client and
    executor, the server and DDS are real; the hold is a dict of rclpy's client that waits when written.
    """

    def __init__(self, client: Any, kind: str, monkeypatch: pytest.MonkeyPatch) -> None:
        from rclpy.action.client import ActionClient

        self.client = client
        self.kind = kind  # "goal", "cancel" or "result": the key of rclpy's taken data and of its flags
        self.cond = threading.Condition()
        self.armed = False
        self.held = False  # the caller is held in the window now
        self.was_held = False  # it was (the test is void otherwise)
        self.seen_ready = 0  # times the executor found the response ready while the caller was held
        self.handled = False  # rclpy's execute ran with the response
        race = self
        is_ready, execute = ActionClient.is_ready, ActionClient.execute

        def watched_is_ready(self: Any, wait_set: Any) -> Any:
            ready = is_ready(self, wait_set)
            if self is race.client and getattr(self, f"_is_{race.kind}_response_ready"):
                with race.cond:
                    if race.held:
                        race.seen_ready += 1
                        race.cond.notify_all()
            return ready

        async def watched_execute(self: Any, taken_data: Any) -> None:
            await execute(self, taken_data)
            if self is race.client and race.kind in taken_data:
                with race.cond:
                    race.handled = True
                    race.cond.notify_all()

        monkeypatch.setattr(ActionClient, "is_ready", watched_is_ready)
        monkeypatch.setattr(ActionClient, "execute", watched_execute)

        class Holding(dict):  # type: ignore[type-arg]
            def __setitem__(self, key: Any, value: Any) -> None:
                race.hold()
                super().__setitem__(key, value)

        pending = f"_pending_{kind}_requests"
        monkeypatch.setattr(client, pending, Holding(getattr(client, pending)))

    def hold(self) -> None:
        with self.cond:
            if not self.armed:
                return
            self.armed = False
            self.held = self.was_held = True
            # a bound only against hanging forever should rclpy change its window (then the test fails below)
            released = self.cond.wait_for(lambda: self.handled or self.seen_ready >= 2, 60.0)
            self.held = False
        assert released, f"the {self.kind} response never came"


def _rclpy_client(fibo: Any) -> Any:
    fibo._fibonacci.register()
    return fibo._fibonacci.client


@pytest.fixture
def threaded_fibo(fibo_adaptor: ModuleType, ros_node: Any, fibo_server: FiboServer) -> Iterator[Any]:
    """A component on a node of its own, spun by a multi-threaded executor (two threads)."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    node: Any = rclpy.create_node("adaptor_test_threaded", context=ros_node.context)
    executor = MultiThreadedExecutor(num_threads=2, context=ros_node.context)
    executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    try:
        yield fibo_adaptor.MathComponent(node, ROBOT, timeout=10.0, wait_timeout=15.0)
    finally:
        executor.shutdown(timeout_sec=5)
        thread.join(5)
        node.destroy_node()


@pytest.mark.parametrize("kind", ["goal", "result", "cancel"])
def test_a_response_that_beats_rclpys_bookkeeping_is_not_lost(
    kind: str, fibo_adaptor: ModuleType, fibo: Any, request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A goal request is sent in the caller's thread, a cancel request too; a result request is sent in the
    executor's thread that takes the acceptance, which a response can beat only when another thread of a
    multi-threaded executor takes it: the result case runs there."""
    if kind == "result":
        fibo = request.getfixturevalue("threaded_fibo")
    fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=1)).result(timeout=10.0)  # the server is known
    race = ResponseRace(_rclpy_client(fibo), kind, monkeypatch)
    if kind == "goal":
        race.armed = True
        handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=2))
        assert list(handle.result(timeout=10.0).sequence) == _sequence(2)
    elif kind == "result":
        race.armed = True  # order 0 ends at once: the result response answers the result request at once
        handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=0))
        assert list(handle.result(timeout=10.0).sequence) == [0]
    else:
        handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=200))
        next(iter(handle.feedback(timeout=10.0)))
        race.armed = True
        assert handle.cancel(timeout=10.0) is True
        with pytest.raises(fibo_adaptor.GoalCanceled):
            handle.result(timeout=10.0)
    assert race.was_held


def _waiting(client: Any, context: Any, timeout: float) -> tuple[bool, ...]:
    """What of rclpy's action `client` waits in the middleware (feedback, status, goal, cancel and result
    response), after at most `timeout` seconds of a wait set of its own (nothing is taken)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

    count = client.get_num_entities()
    with context.handle:
        wait_set = _rclpy.WaitSet(
            count.num_subscriptions,
            count.num_guard_conditions,
            count.num_timers,
            count.num_clients,
            count.num_services,
            count.num_events,
            context.handle,
        )
        wait_set.clear_entities()
        client.add_to_wait_set(wait_set)
        wait_set.wait(int(timeout * 1e9))
        return tuple(client._client_handle.is_ready(wait_set))


def test_feedback_waiting_beside_a_status_array_is_told_before_the_array_is_taken(
    fibo: Any, ros_node: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A server publishes its status array (every goal it keeps, for 15 minutes by default) on each change of
    any goal, right before a goal's first feedback; converting an array of a hundred goals costs the executor
    about a millisecond. When a turn finds feedback and a status array waiting, the feedback is told first
    and the array taken after it. The executor is held in the goal's on_accepted until the server's status
    array and first feedback both wait (a wait set of the test's own looks, taking nothing), so one turn
    finds both (with the result, as it happens: the server's next array is its last)."""
    client = _rclpy_client(fibo)
    fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=1)).result(timeout=10.0)  # the server is known
    told: list[str] = []
    statuses = client._statuses
    monkeypatch.setattr(client, "_statuses", lambda array: (told.append("status"), statuses(array)))
    both: list[bool] = []

    def on_accepted() -> None:  # the executor's thread: no turn until both wait
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and not both:
            feedback, status = _waiting(client, ros_node.context, 0.1)[:2]
            if feedback and status:
                both.append(True)
        told.clear()

    done = threading.Event()
    fibo.start_fibonacci(
        fibo.construct_fibonacci_Goal(order=3),
        on_accepted=on_accepted,
        on_feedback=lambda _message: told.append("feedback"),
        on_done=lambda _outcome: done.set(),
    )
    assert done.wait(10.0), "the goal never ended"
    assert both, "the server's status array and first feedback never waited together"
    assert "feedback" in told and "status" in told, told
    assert told.index("feedback") < told.index("status"), told


def test_a_blocking_calls_waiter_is_woken_in_the_turn_that_completed_its_future(
    fibo_adaptor: ModuleType, ros_node: Any
) -> None:
    """rclpy attaches a client's future to the executor just before completing it, so its done callbacks
    run as executor tasks a whole turn later; the runtime has a blocking call's callback (it only sets the
    caller's event) run in place, right when the response completes the future (bench: about 0.7 ms of a
    3 ms service call). Checked against rclpy's own Future and executor."""
    import rclpy.task
    from rclpy.executors import SingleThreadedExecutor

    runtime = importlib.import_module(f"{fibo_adaptor.__name__}.runtime")
    executor = SingleThreadedExecutor(context=ros_node.context)  # never spun: a task scheduled on it stays there
    try:
        for in_turn in (False, True):
            future: Any = rclpy.task.Future()
            if in_turn:
                runtime._callbacks_in_turn(future)
            ran: list[str] = []
            future.add_done_callback(lambda _f, ran=ran: ran.append(threading.current_thread().name))
            future._set_executor(executor)  # what rclpy's executor does before it completes a client's future
            future.set_result("the response")
            assert ran == ([threading.current_thread().name] if in_turn else []), in_turn
    finally:
        executor.shutdown()


class _DropFirstGoalResponse:
    """An rclpy ActionServer's C handle that drops the first goal response it is asked to send: the fault of a
    Fast DDS server answering a client whose reply reader it has not matched yet (right after discovery),
    which cannot be produced on demand."""

    def __init__(self, handle: Any) -> None:
        self._inner = handle
        self.dropped = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def __enter__(self) -> Any:
        return self._inner.__enter__()

    def __exit__(self, *exc: object) -> Any:
        return self._inner.__exit__(*exc)

    def send_goal_response(self, header: Any, response: Any) -> None:
        if self.dropped == 0:
            self.dropped = 1
            return
        self._inner.send_goal_response(header, response)


def test_a_lost_goal_response_is_recovered_from_the_servers_status(
    fibo: Any, fibo_server: FiboServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The server accepts the goal but its response never arrives: the goal is in the server's status list, so
    the request completes as accepted from there (a resent request would be refused as a duplicate goal id)
    and the goal is followed to its result, well before the call's timeout (10 s)."""
    fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=1)).result(timeout=10.0)  # the server is known
    drop = _DropFirstGoalResponse(fibo_server.server._handle)
    monkeypatch.setattr(fibo_server.server, "_handle", drop)
    started = time.monotonic()
    handle = fibo.send_fibonacci(fibo.construct_fibonacci_Goal(order=4))
    assert drop.dropped == 1, "the goal response was dropped"
    assert list(handle.result(timeout=10.0).sequence) == _sequence(4)
    assert handle.status == "succeeded"
    assert time.monotonic() - started < 5.0


# -- the callback API (start_X): the scenarios of tests.backends.goal_scenarios, the same as on ROS 1


def test_a_burst_of_1000_feedback_messages_is_told_once_each_in_order_then_one_end(fibo: Any) -> None:
    """The server publishes 1,000 feedback messages back to back and succeeds: on_feedback gets each once, in
    order, between on_accepted and exactly one on_done, all in the executor's thread; the blocking iterator
    reads the same buffer. A lost or repeated message fails check_burst (goal_scenarios)."""
    goal = fibo.construct_fibonacci_Goal(order=BURST + 1000)
    out = goal_scenarios.burst(lambda **callbacks: fibo.start_fibonacci(goal, **callbacks))
    goal_scenarios.check_burst(out, 1000)
    assert out["threads"] == ["adaptor-spinner"]  # the thread of the executor that spins the node


def test_cancel_through_the_callback_api(fibo: Any) -> None:
    goal = fibo.construct_fibonacci_Goal(order=200)
    goal_scenarios.check_cancel(goal_scenarios.cancel(lambda **callbacks: fibo.start_fibonacci(goal, **callbacks)))


def test_a_killed_server_ends_the_goal_through_on_done_with_no_thread_waiting_on_it(
    fibo_adaptor: ModuleType, ros_node: Any
) -> None:
    """SIGKILL to the action server's process mid-goal: the node's goal timer (no thread of the goal's own)
    finds it gone within the handle's server_timeout and ends the goal lost through on_done."""
    server = Process([sys.executable, "-m", "tests.runtime.fibo_ros2", "fibo_doomed_cb"], env.child_env([]))
    try:
        server.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        component = fibo_adaptor.MathComponent(ros_node, "fibo_doomed_cb", timeout=10.0, wait_timeout=15.0)

        def start(**callbacks: Any) -> Any:
            handle = component.start_fibonacci(component.construct_fibonacci_Goal(order=1000), **callbacks)
            handle.server_timeout = 1.0
            return handle

        def warm(**callbacks: Any) -> Any:
            return component.start_fibonacci(component.construct_fibonacci_Goal(order=1), **callbacks)

        def kill() -> None:
            server.proc.send_signal(signal.SIGKILL)
            server.proc.wait(10)

        out = goal_scenarios.killed(start, kill, warm)
    finally:
        server.stop()
    goal_scenarios.check_killed(out, bound=1.0 + 2.0)


def test_50_concurrent_goals_start_no_thread(fibo_adaptor: ModuleType, ros_node: Any) -> None:
    from tests.runtime.fibo_ros2 import FAST, sequence

    server = Process([sys.executable, "-m", "tests.runtime.fibo_ros2", "fibo_many"], env.child_env([]))
    try:
        server.wait_for(lambda e: e.get("event") == "ready", timeout=30)
        component = fibo_adaptor.MathComponent(ros_node, "fibo_many", timeout=20.0, wait_timeout=15.0)
        goal = component.construct_fibonacci_Goal(order=FAST + 5)
        out = goal_scenarios.concurrent(lambda **callbacks: component.start_fibonacci(goal, **callbacks), 50)
    finally:
        server.stop()
    goal_scenarios.check_concurrent(out, [sequence(i) for i in range(1, 6)], sequence(40))


def test_goal_ids_are_distinct_and_start_x_reads_no_random_bytes_from_the_system(
    fibo_adaptor: ModuleType, fibo: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A goal id is 16 bytes unique in the process without a system call per goal (os.urandom lets go of the
    interpreter lock, and start_X then waits for the executor's thread to give it back)."""
    import os

    drawn: list[int] = []
    urandom = os.urandom

    def counting(n: int) -> bytes:
        drawn.append(n)
        return urandom(n)

    monkeypatch.setattr(os, "urandom", counting)
    done = threading.Event()
    ends: list[Any] = []

    def on_done(outcome: Any) -> None:
        ends.append(outcome)
        if len(ends) == 20:
            done.set()

    goal = fibo.construct_fibonacci_Goal(order=1)
    handles = [fibo.start_fibonacci(goal, on_done=on_done) for _ in range(20)]
    assert not drawn, f"start_X read {len(drawn)} random numbers from the system"
    monkeypatch.undo()
    ids = [h.goal_id for h in handles]
    assert len(set(ids)) == 20 and all(len(i) == 32 and int(i, 16) >= 0 for i in ids)
    assert done.wait(15) and all(o.status == "succeeded" for o in ends), ends


def test_rejoin_follows_a_goal_another_client_sent_by_its_id(
    fibo_adaptor: ModuleType, fibo: Any, ros_node: Any
) -> None:
    """`rejoin_X` (issue 32): a second client (another component, its own ActionClient) follows a running goal by
    its id: on_accepted, the feedback from then on, in order, and one on_done with the server's result; a goal id
    the server does not know ends lost at once (never hangs); a malformed id is refused."""
    sent = fibo.start_fibonacci(fibo.construct_fibonacci_Goal(order=40))  # 2 s
    first = next(iter(sent.feedback(timeout=5.0)))
    assert list(first.sequence) == _sequence(1)
    other = fibo_adaptor.MathComponent(ros_node, ROBOT, timeout=10.0, wait_timeout=15.0)
    told: list[str] = []
    seen: list[int] = []
    ended = threading.Event()
    handle = other.rejoin_fibonacci(
        sent.goal_id,
        on_accepted=lambda: told.append("accepted"),
        on_feedback=lambda fb: seen.append(len(fb.sequence)),
        on_done=lambda outcome: (told.append(outcome.status), ended.set()),
    )
    assert handle.goal_id == sent.goal_id
    assert ended.wait(15.0)
    assert told == ["accepted", "succeeded"], told
    assert list(handle.result(timeout=1.0).sequence) == _sequence(40)
    assert seen and seen == sorted(seen) and seen[-1] == 41 and len(seen) >= 10, seen  # the rest of its feedback

    stranger = other.rejoin_fibonacci("ab" * 16)
    with pytest.raises(fibo_adaptor.CallFailed, match="does not know goal " + "ab" * 16):
        stranger.result(timeout=10.0)
    assert stranger.outcome is not None and stranger.outcome.status == "lost"
    with pytest.raises(ValueError, match="32 hexadecimal digits"):
        other.rejoin_fibonacci("not-a-goal")


def test_rejoin_tells_an_acceptance_only_of_a_goal_the_server_has_and_never_steps_its_status_back(
    fibo_adaptor: ModuleType, fibo: Any, ros_node: Any
) -> None:
    """`rejoin_X` (issue 32, found by a new user's trial): a goal followed by its id counts as accepted once the
    server shows it has it (its status, its feedback, its result). Before, `on_accepted` and `on_status("accepted")`
    were told of an id the server never had, just before it ended lost, and a goal executing for seconds was told
    `accepted` first (the edge node then answered a query of it `queued` after a restart)."""
    other = fibo_adaptor.MathComponent(ros_node, ROBOT, timeout=10.0, wait_timeout=15.0)
    told: list[str] = []
    ended = threading.Event()
    stranger = other.rejoin_fibonacci(
        "cd" * 16,
        on_accepted=lambda: told.append("accepted"),
        on_status=lambda status: told.append(f"status {status}"),
        on_done=lambda outcome: (told.append(outcome.status), ended.set()),
    )
    assert ended.wait(15.0)
    assert told == ["lost"], told
    assert stranger.status != "accepted"
    # no result: the server's answer for a goal it does not know is a default one (zeros an application could
    # take for real values; a new user's dock charger ended lost with `final_percent: 0.0`)
    assert stranger.outcome.result is None, stranger.outcome
    assert getattr(stranger.outcome.error, "response", None) is None

    sent = fibo.start_fibonacci(fibo.construct_fibonacci_Goal(order=40))  # 2 s
    next(iter(sent.feedback(timeout=5.0)))
    followed: list[str] = []
    done = threading.Event()
    other.rejoin_fibonacci(
        sent.goal_id,
        on_accepted=lambda: followed.append("accepted"),
        on_status=lambda status: followed.append(f"status {status}"),
        on_done=lambda outcome: (followed.append(outcome.status), done.set()),
    )
    assert done.wait(15.0)
    assert followed[0] == "accepted" and followed[-1] == "succeeded", followed
    assert "status accepted" not in followed, followed  # it executed all along
