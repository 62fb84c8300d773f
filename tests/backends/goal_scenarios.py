"""The generated goal API's callbacks (`start_X`), exercised the same way on ROS 2 and ROS 1.

Each scenario takes `start(**callbacks)`, which starts one goal through a generated component (the caller
picks the component, the action and the goal: the ROS 1 and ROS 2 test servers differ in names only), and
returns what the callbacks were told as plain data (JSON: the ROS 1 scenarios run under Debian's Python, in a
client process). The `check_*` functions assert on that data in the test process, the same for both.

Plain Python, no pytest: imported by the rclpy tests in-process and by the rospy tests' client processes.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import Any

#: after the goal's end was told: how long a second end or feedback told after it would still be seen
QUIET = 0.3
#: bounded waits of the scenarios (generous: a loaded CI machine)
WAIT = 60.0

Start = Callable[..., Any]


class Recorder:
    """The callbacks of one goal: what they are told, in order, in which threads, and whether two of them ever
    ran at once."""

    def __init__(self) -> None:
        self.events: list[list[Any]] = []
        self.threads: set[str] = set()
        self.overlap = False
        self.peak_threads = 0
        self.done_at = 0.0
        self.first_feedback = threading.Event()
        self.done = threading.Event()
        self._busy = False
        self._lock = threading.Lock()

    def callbacks(self) -> dict[str, Callable[..., None]]:
        return {
            "on_accepted": self.on_accepted,
            "on_status": self.on_status,
            "on_feedback": self.on_feedback,
            "on_done": self.on_done,
        }

    def _told(self, *event: Any) -> None:
        with self._lock:
            self.overlap = self.overlap or self._busy
            self._busy = True
            self.events.append(list(event))
            self.threads.add(threading.current_thread().name)
            self.peak_threads = max(self.peak_threads, threading.active_count())
        time.sleep(0)  # let another thread in: an overlapping callback would be seen here
        with self._lock:
            self._busy = False

    def on_accepted(self) -> None:
        self._told("accepted")

    def on_status(self, status: str) -> None:
        self._told("status", status)

    def on_feedback(self, message: Any) -> None:
        self._told("feedback", [int(x) for x in message.sequence])
        self.first_feedback.set()

    def on_done(self, outcome: Any) -> None:
        result = None if outcome.result is None else [int(x) for x in outcome.result.sequence]
        error = None if outcome.error is None else type(outcome.error).__name__
        self._told("done", outcome.status, result, error)
        self.done_at = time.monotonic()
        self.done.set()

    def summary(self) -> dict[str, Any]:
        with self._lock:
            return {
                "kinds": [e[0] for e in self.events],
                "statuses": [e[1] for e in self.events if e[0] == "status"],
                "feedback": [e[1] for e in self.events if e[0] == "feedback"],
                "done": [e[1:] for e in self.events if e[0] == "done"],
                "threads": sorted(self.threads),
                "overlap": self.overlap,
            }


def waiting_on(handle: Any) -> list[str]:
    """The threads blocked in a wait (innermost frame in threading.py) while an outer frame of theirs works
    for `handle` (its `self`): a thread that follows the goal by waiting on it."""
    names = {t.ident: t.name for t in threading.enumerate()}
    blocked = []
    for ident, frame in sys._current_frames().items():
        if ident == threading.get_ident() or not frame.f_code.co_filename.endswith("threading.py"):
            continue
        outer: Any = frame
        while outer is not None and outer.f_locals.get("self") is not handle:
            outer = outer.f_back
        if outer is not None:
            blocked.append(names.get(ident, str(ident)))
    return blocked


def burst(start: Start) -> dict[str, Any]:
    """A goal whose server sends its feedback in one burst, then its result."""
    recorder = Recorder()
    caller = threading.current_thread().name
    handle = start(**recorder.callbacks())
    ended = recorder.done.wait(WAIT)
    time.sleep(QUIET)  # a second end, or feedback told after the end, would show in this window
    iterated = [[int(x) for x in m.sequence] for m in handle.feedback(timeout=5.0)]
    return {
        **recorder.summary(),
        "ended": ended,
        "caller": caller,
        "goal_id": str(handle.goal_id),
        "received": int(handle.feedback_received),
        "iterated": iterated,
        "status": str(handle.status),
    }


def cancel(start: Start) -> dict[str, Any]:
    """A long goal canceled through `request_cancel` once its first feedback came; then a second request, made
    after the end, which is answered False (and not inside the call)."""
    recorder = Recorder()
    handle = start(**recorder.callbacks())
    assert recorder.first_feedback.wait(WAIT), "no feedback"
    answers: list[list[Any]] = []
    answered = threading.Event()
    inside = _Inside()

    def on_answer(outcome: Any) -> None:
        error = None if outcome.error is None else type(outcome.error).__name__
        answers.append([outcome.canceling, error, threading.current_thread().name, inside.active])
        answered.set()

    handle.request_cancel(on_answer, timeout=30.0)
    first = answered.wait(WAIT)
    ended = recorder.done.wait(WAIT)
    answered.clear()
    inside.active = True  # an answer told inside the call (in this thread) would say so
    handle.request_cancel(on_answer, timeout=30.0)
    inside.active = False
    second = answered.wait(WAIT)
    time.sleep(QUIET)
    return {
        **recorder.summary(),
        "answers": answers,
        "answered": [first, second],
        "ended": ended,
        "caller": threading.current_thread().name,
    }


class _Inside(threading.local):
    """Per thread: whether this thread is inside a call being watched."""

    active = False


def killed(start: Start, kill: Callable[[], None], warm: Start) -> dict[str, Any]:
    """A long goal whose server is killed once its first feedback came: the goal's end comes to `on_done`, no
    thread waits on the goal meanwhile (a control thread that does is seen by the same check), and no thread
    was started for it (after a short goal through the same client, `warm`: the client's own connections)."""
    warmed = Recorder()
    warm(**warmed.callbacks())
    assert warmed.done.wait(WAIT), "the warm-up goal did not end"
    recorder = Recorder()
    before = {t.name for t in threading.enumerate()}
    handle = start(**recorder.callbacks())
    assert recorder.first_feedback.wait(WAIT), "no feedback"
    new_threads = sorted({t.name for t in threading.enumerate()} - before)
    blocked_before = waiting_on(handle)
    errors: list[str] = []

    def control() -> None:
        try:
            handle.result(timeout=WAIT)
        except Exception as exc:  # noqa: BLE001 - its kind is the finding
            errors.append(type(exc).__name__)

    waiter = threading.Thread(target=control, name="control-waiter", daemon=True)
    waiter.start()
    deadline = time.monotonic() + WAIT
    seen: list[str] = []
    while not seen and time.monotonic() < deadline:
        seen = waiting_on(handle)
        time.sleep(0.01)
    kill()
    killed_at = time.monotonic()
    ended = recorder.done.wait(WAIT)
    waiter.join(WAIT)
    return {
        **recorder.summary(),
        "new_threads": new_threads,
        "blocked_before": blocked_before,
        "control_seen": seen,
        "control_errors": errors,
        "ended": ended,
        "after_kill": recorder.done_at - killed_at if ended else None,
        "done_flag": bool(handle.done),
        "caller": threading.current_thread().name,
    }


def concurrent(start: Start, goals: int) -> dict[str, Any]:
    """`goals` goals in flight at once (after one goal that starts whatever the API starts once per process):
    the process's threads, counted before, at every callback, and after."""
    warm = Recorder()
    start(**warm.callbacks())
    assert warm.done.wait(WAIT), "the warm-up goal did not end"
    before = threading.active_count()
    recorders = [Recorder() for _ in range(goals)]
    for recorder in recorders:
        start(**recorder.callbacks())
    ended = all(recorder.done.wait(WAIT) for recorder in recorders)
    time.sleep(QUIET)
    return {
        "threads_before": before,
        "threads_peak": max(recorder.peak_threads for recorder in recorders),
        "threads_after": threading.active_count(),
        "ended": ended,
        "goals": [recorder.summary() for recorder in recorders],
        "caller": threading.current_thread().name,
    }


# -- the checks, the same for both ROS versions (in the test process)


def check_story(story: dict[str, Any], caller: str) -> None:
    """One goal's story as the API promises it: accepted first, one end last, never two callbacks at once,
    never in the caller's thread."""
    kinds = story["kinds"]
    assert kinds[0] == "accepted" and kinds.count("accepted") == 1, kinds[:5]
    assert kinds.count("done") == 1 and kinds[-1] == "done", kinds[-5:]
    assert not story["overlap"], "two callbacks of one goal ran at once"
    assert caller not in story["threads"], story["threads"]


def check_burst(out: dict[str, Any], n: int) -> None:
    assert out["ended"], "no on_done"
    check_story(out, out["caller"])
    expected = [[i] for i in range(1, n + 1)]
    feedback = out["feedback"]
    # every message exactly once, in order: a lost or a duplicated one fails here, and says which
    missing = sorted({i for i in range(1, n + 1)} - {f[0] for f in feedback})
    repeated = sorted({f[0] for f in feedback if feedback.count(f) > 1})
    assert feedback == expected, f"{len(feedback)} told, missing {missing[:10]}, repeated {repeated[:10]}"
    assert out["done"] == [["succeeded", [n], None]]
    assert out["received"] == n and out["iterated"] == expected  # the blocking iterator reads the same buffer
    assert out["status"] == "succeeded" and out["goal_id"]


def check_killed(out: dict[str, Any], bound: float) -> None:
    """The killed server's goal: lost through on_done within `bound` seconds of the kill, with no thread of
    the API waiting on it (the control thread that waited was seen, and ended too)."""
    assert out["ended"], "no on_done after the server was killed"
    check_story(out, out["caller"])
    assert out["done"] == [["lost", None, "ServiceUnavailable"]] and not out["done_flag"]
    assert out["after_kill"] < bound, out["after_kill"]
    assert out["blocked_before"] == [], out["blocked_before"]
    assert out["control_seen"] == ["control-waiter"] and out["control_errors"] == ["ServiceUnavailable"]
    assert out["new_threads"] == [], out["new_threads"]


def check_concurrent(out: dict[str, Any], feedback: list[list[int]], result: list[int]) -> None:
    """Every goal told its whole story; the process had no more threads while they ran than before."""
    assert out["ended"]
    for story in out["goals"]:
        check_story(story, out["caller"])
        told = (story["feedback"], story["done"], story["kinds"][-6:])
        assert story["feedback"] == feedback and story["done"] == [["succeeded", result, None]], told
    assert out["threads_peak"] <= out["threads_before"], (out["threads_before"], out["threads_peak"])
    assert out["threads_after"] <= out["threads_before"], (out["threads_before"], out["threads_after"])


def check_cancel(out: dict[str, Any]) -> None:
    assert out["ended"] and out["answered"] == [True, True]
    check_story(out, out["caller"])
    (canceling, error, thread, inside), (again, again_error, again_thread, again_inside) = out["answers"]
    assert (canceling, error) == (True, None)
    assert (again, again_error) == (False, None)  # over already
    assert thread != out["caller"] and again_thread != out["caller"] and not inside and not again_inside
    ((status, result, kind),) = out["done"]
    assert (status, kind) == ("canceled", "GoalCanceled") and result is not None
    assert out["feedback"], "no feedback before the cancel"
