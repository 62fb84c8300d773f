"""The engine's loop, call pool and lanes (runtime/loop.py), and a robot whose calls hang beside one that answers."""

from __future__ import annotations

import gc
import subprocess
import sys
import threading
import time
import weakref
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.loop import CALL_THREADS, COMPACT_AT, CallPool, Lane, Loop, Timer
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import GOAL, LocalApp, rb1_model, sim, terminal

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def loop() -> Any:
    loop = Loop(name="test-loop")
    yield loop
    loop.stop()


def test_posted_callbacks_run_in_order_on_the_loop_and_a_failing_one_costs_itself(loop: Loop) -> None:
    seen: list[tuple[int, str]] = []
    done = threading.Event()

    def note(i: int) -> None:
        seen.append((i, threading.current_thread().name))
        if i == 2:
            raise RuntimeError("a bug in one callback")

    for i in range(100):
        loop.post(note, i)
    loop.post(done.set)
    assert done.wait(5)
    assert [i for i, _ in seen] == list(range(100))
    assert {name for _, name in seen} == {"test-loop"}


def test_timers_run_when_due_in_order_and_a_cancelled_one_never(loop: Loop) -> None:
    ran: list[str] = []
    done = threading.Event()
    loop.call_later(0.15, ran.append, "late")
    loop.call_later(0.05, ran.append, "early")
    loop.call_later(0.10, ran.append, "cancelled").cancel()
    loop.call_later(0.20, done.set)
    begin = time.monotonic()
    assert done.wait(5)
    assert ran == ["early", "late"]
    assert time.monotonic() - begin >= 0.19


class _Held:
    """Something a timer's callback holds (a weak reference says whether it is still alive)."""


def test_a_cancelled_timer_lets_go_of_what_its_callback_holds_at_once(loop: Loop) -> None:
    held = _Held()
    alive = weakref.ref(held)
    timer = loop.call_later(600, lambda _held: None, held)  # a goal's mission timeout, cancelled when it ends
    del held
    timer.cancel()
    assert alive() is None, "a cancelled timer kept its callback's objects alive until it would have been due"


def test_cancelled_timers_do_not_pile_up_in_the_loop_and_the_others_still_run_in_order(loop: Loop) -> None:
    ran: list[int] = []
    done = threading.Event()
    for i in range(5_000):  # a quick call's guard each: set, then cancelled when the call is answered
        loop.call_later(25 + i / 1000, ran.append, -i).cancel()
        if i % 1000 == 0:
            loop.call_later(0.05 + i / 100_000, ran.append, i)
    loop.call_later(0.2, done.set)
    timers = sum(isinstance(o, Timer) for o in gc.get_objects())
    assert timers <= 2 * COMPACT_AT + 10, f"{timers} timers alive after 5,000 were cancelled"
    assert done.wait(5)
    assert ran == [0, 1000, 2000, 3000, 4000]


def test_timers_cancelled_from_other_threads_while_the_loop_runs_its_own_leave_it_serving(loop: Loop) -> None:
    ran: list[int] = []
    stop = threading.Event()

    def churn() -> None:  # the port's threads: a guard set and cancelled for each answered call
        while not stop.is_set():
            for _ in range(200):
                loop.call_later(25, ran.append, -1).cancel()

    churners = [threading.Thread(target=churn) for _ in range(2)]
    for thread in churners:
        thread.start()
    try:
        done = threading.Event()
        for i in range(300):  # the loop's own short timers (polls), due while the heap is rebuilt
            loop.call_later(i / 1000, ran.append, i)
        loop.call_later(0.35, done.set)
        assert done.wait(10)
    finally:
        stop.set()
        for thread in churners:
            thread.join(10)
    assert sorted(ran) == list(range(300)), "a timer was lost, or a cancelled one ran"
    assert loop.thread.is_alive()


def test_a_timer_set_from_another_thread_wakes_a_loop_asleep_until_a_later_one(loop: Loop) -> None:
    done = threading.Event()
    loop.call_later(60, done.set)  # the loop sleeps until this one
    woke = threading.Event()
    begin = time.monotonic()
    loop.call_later(0.01, woke.set)
    assert woke.wait(5) and time.monotonic() - begin < 5
    assert not done.is_set()


def test_call_returns_the_result_or_raises_and_runs_inline_on_the_loop(loop: Loop) -> None:
    assert loop.call(lambda: threading.current_thread().name) == "test-loop"
    with pytest.raises(ValueError, match="bad"):
        loop.call(lambda: (_ for _ in ()).throw(ValueError("bad")))
    assert loop.call(lambda: loop.call(lambda: 42)) == 42  # from the loop itself: inline, no deadlock


def test_a_lane_runs_at_most_its_limit_at_once_in_order() -> None:
    pool = CallPool(6, name="test-call")
    try:
        lane = Lane(pool, limit=2)
        lock = threading.Lock()
        running, most, order = [0], [0], []
        gate = threading.Event()

        def task(i: int) -> None:
            with lock:
                running[0] += 1
                most[0] = max(most[0], running[0])
                order.append(i)
            gate.wait(5)
            with lock:
                running[0] -= 1

        for i in range(10):
            lane.submit(lambda i=i: task(i))  # type: ignore[misc]
        assert lane.busy() == 10
        time.sleep(0.1)  # the pool has 6 threads: were the lane not bounded, more than 2 would run by now
        assert most[0] == 2
        gate.set()
        assert lane.wait_idle(5)
        assert most[0] == 2 and order == list(range(10)) and lane.busy() == 0
    finally:
        pool.stop()


SHARED = """
import threading
from td2adaptor.runtime.loop import CALL_THREADS, acquire, release
before = threading.active_count()
first, second = acquire(), acquire()
assert first is second
assert threading.active_count() == before + 1 + CALL_THREADS
release(first)
assert first.loop.thread.is_alive()
release(second)
assert not first.loop.thread.is_alive() and not any(t.is_alive() for t in first.pool.threads)
assert threading.active_count() == before
third = acquire()  # a later engine gets a fresh pair
assert third is not first and third.loop.thread.is_alive()
release(third)
print("ok")
"""


def test_the_shared_loop_and_pool_start_once_and_end_with_their_last_user() -> None:
    """In a process of its own: in this one, another test may have left an engine running."""
    proc = subprocess.run([sys.executable, "-c", SHARED], capture_output=True, text=True, timeout=60, cwd=REPO)
    assert (proc.returncode, proc.stdout.strip()) == (0, "ok"), proc.stderr


def test_a_robot_whose_calls_hang_holds_a_few_pool_threads_and_the_others_go_on() -> None:
    """Robot a's robot takes 3 s per call and gets more queries than the pool has threads; robot b's mission
    runs to its end meanwhile: robot a holds `ROBOT_CALLS` threads of the pool, never all of them."""
    broker = LocalBroker()
    model = rb1_model()
    app = LocalApp(broker)
    slow = SimPort(model, sim(0.2, robot_id="lane_a"))
    slow.delay = 3.0
    fast = SimPort(model, sim(0.2, robot_id="lane_b"))
    base: dict[str, Any] = {"poll_period": 0.02, "property_period": 0, "call_timeout": 10.0, "state_dir": ""}
    engines = [
        serve(model, slow, RuntimeConfig(robot="lane_a", **base), broker=broker),
        serve(model, fast, RuntimeConfig(robot="lane_b", **base), broker=broker),
    ]
    try:
        for i in range(CALL_THREADS + 8):
            app.send("td2adaptor/lane_a/GoToComponent/gotoQuery", {"correlation": f"q{i}", "mission": 1})
        begin = time.monotonic()
        app.send("td2adaptor/lane_b/GoToComponent/gotoRun", {"correlation": "b", "payload": GOAL})
        app.wait(terminal("feedback", "b"), 10)
        assert time.monotonic() - begin < 3.0  # before the slow robot's first answer
        assert app.of("feedback", "b")[-1]["payload"]["state"] == "finished"
        assert not app.of("state")  # none of robot a's queries is answered yet
    finally:
        for engine in engines:
            engine.stop()
