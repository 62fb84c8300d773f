"""The engine's threads, one set per process however many robots and missions it serves.

* `Loop`: one thread (`td2adaptor-engine`) that runs callbacks in the order they were posted and timers when
  they are due (a heap). Every robot's inbound events are handled there one at a time, in arrival order, and
  every procedure mission is a state machine that lives there: its next query is a timer, a robot call's
  answer comes back as a posted callback. What is only ever touched on this thread needs no lock.
* `CallPool`: `CALL_THREADS` threads (`td2adaptor-call-N`), all started at once, that make the robot calls
  (they block until the robot answers or `call_timeout`); a `Lane` is one robot's share of it, at most
  `ROBOT_CALLS` of its calls at a time, the rest waiting in order, so that a robot whose calls hang holds a
  few threads, never the whole pool.
* `shared()`: the process's one loop and pool, started with the first engine and stopped with the last.

A thread per mission (the previous design) made the thread count grow with the missions in flight and each
poll a sleep in its own thread; a dispatcher and a pool per robot made it grow with the robots (4 per robot).
Standard library only; nothing here knows what a robot is.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

log = logging.getLogger("td2adaptor.runtime")

#: threads of the process's call pool: robot calls in flight at once, all robots together
CALL_THREADS = 32
#: calls of one robot in flight at once (its other calls wait for one of these to end)
ROBOT_CALLS = 8
#: cancelled timers a loop's heap holds at least before it is rebuilt without them (when they are most of it)
COMPACT_AT = 64

Task = Callable[[], None]


class Timer:
    """A callback due at `when` (the loop's clock); `cancel()` it before then and it does not run.

    A cancelled timer lets go of its callback and arguments at once, and the loop drops cancelled timers from
    its heap once they are most of it: a long timer cancelled early (a quick call's guard, 25 s by default; a
    goal's mission timeout, 600 s) kept every object its callback reached alive until it was due, thousands of
    them in a busy fleet, and each full pass of Python's garbage collector walked them all while every thread
    waited (100 RB-1s at 1 mission/s: about 60,000 more objects within 30 s; docs/performance.md)."""

    __slots__ = ("_loop", "args", "cancelled", "fn", "queued", "when")

    def __init__(self, when: float, fn: Callable[..., None], args: tuple[Any, ...], loop: Loop | None = None) -> None:
        self.when = when
        self.fn = fn
        self.args = args
        self.cancelled = False
        self.queued = False  # in its loop's heap (under the loop's lock)
        self._loop = loop

    def cancel(self) -> None:
        loop = self._loop
        if loop is None:
            self.cancelled, self.fn, self.args = True, _nothing, ()
            return
        loop._drop(self)


class Loop:
    """One thread running posted callbacks in order and timers when due (see the module docstring). A callback
    that raises is logged: it costs itself, never the loop."""

    def __init__(self, name: str = "td2adaptor-engine", clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._inbox: queue.SimpleQueue[tuple[Callable[..., None], tuple[Any, ...]] | None] = queue.SimpleQueue()
        self._timers: list[tuple[float, int, Timer]] = []  # a heap; pushed under _lock from other threads
        self._cancelled = 0  # timers of the heap cancelled (under _lock)
        self._lock = threading.Lock()
        self._order = itertools.count()
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.thread.start()

    def on_loop(self) -> bool:
        """Whether the caller runs on the loop's thread."""
        return threading.current_thread() is self.thread

    def post(self, fn: Callable[..., None], *args: Any) -> None:
        """Run `fn(*args)` on the loop's thread, after everything posted before (any thread)."""
        self._inbox.put((fn, args))

    def call_later(self, delay: float, fn: Callable[..., None], *args: Any) -> Timer:
        """Run `fn(*args)` on the loop's thread in `delay` seconds, unless cancelled first (any thread)."""
        timer = Timer(self.clock() + max(0.0, delay), fn, args, self)
        with self._lock:
            heapq.heappush(self._timers, (timer.when, next(self._order), timer))
            timer.queued = True
        if not self.on_loop():  # the loop may sleep until a later timer: it looks again
            self._inbox.put((_nothing, ()))
        return timer

    def call(self, fn: Callable[[], Any], timeout: float | None = None) -> Any:
        """Run `fn()` on the loop's thread and return its result (inline when already there); waits at most
        `timeout` seconds when given (then raises TimeoutError)."""
        if self.on_loop():
            return fn()
        done = threading.Event()
        box: list[Any] = []

        def run() -> None:
            try:
                box.append((True, fn()))
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                box.append((False, exc))
            finally:
                done.set()

        self.post(run)
        if not done.wait(timeout):
            raise TimeoutError("the engine's loop did not answer in time")
        ok, value = box[0]
        if not ok:
            raise value
        return value

    def _drop(self, timer: Timer) -> None:
        """Cancel `timer` (Timer.cancel, any thread): it lets go of its callback now, and the heap is rebuilt
        without the cancelled timers once they are more than half of it (and `COMPACT_AT` at least)."""
        with self._lock:
            if timer.cancelled:
                return
            timer.cancelled, timer.fn, timer.args = True, _nothing, ()
            if not timer.queued:
                return
            self._cancelled += 1
            if self._cancelled >= COMPACT_AT and 2 * self._cancelled > len(self._timers):
                kept = [entry for entry in self._timers if not entry[2].cancelled]
                heapq.heapify(kept)
                self._timers, self._cancelled = kept, 0

    def stop(self, timeout: float = 5.0) -> None:
        """End the thread after what was posted so far (timers not yet due are dropped)."""
        self._inbox.put(None)
        if not self.on_loop():
            self.thread.join(timeout)

    def _due(self) -> float | None:
        """Run the timers that are due; seconds until the next one (None: there is none)."""
        while True:
            with self._lock:
                if not self._timers:
                    return None
                when, _, timer = self._timers[0]
                wait = when - self.clock()
                if wait > 0 and not timer.cancelled:
                    return wait
                heapq.heappop(self._timers)
                timer.queued = False
                if timer.cancelled:
                    self._cancelled -= 1
                    continue
                fn, args = timer.fn, timer.args
            _safely(fn, args)

    def _run(self) -> None:
        inbox = self._inbox
        while True:
            wait = self._due()
            try:
                item = inbox.get(timeout=wait) if wait is not None else inbox.get()
            except queue.Empty:
                continue
            while item is not None:
                _safely(*item)
                try:
                    item = inbox.get_nowait()
                except queue.Empty:
                    break
                timers = self._timers  # one read: another thread may replace it (`_drop` rebuilding the heap)
                if timers and timers[0][0] <= self.clock():  # due timers keep their turn
                    self._due()
            else:
                return


def _nothing() -> None:
    """Posted to make the loop look at its timers again."""


def _safely(fn: Callable[..., None], args: tuple[Any, ...]) -> None:
    try:
        fn(*args)
    except Exception:  # a bug in one callback must cost that callback, not every robot's loop
        log.exception("internal error in the engine's loop")


class CallPool:
    """`size` threads making blocking calls (robot calls), all started at once: the thread count stays what it
    is whatever the load. A task that raises is logged."""

    def __init__(self, size: int = CALL_THREADS, name: str = "td2adaptor-call") -> None:
        self.size = size
        self._tasks: queue.SimpleQueue[Task | None] = queue.SimpleQueue()
        self.threads = [threading.Thread(target=self._work, name=f"{name}-{i + 1}", daemon=True) for i in range(size)]
        for thread in self.threads:
            thread.start()

    def submit(self, task: Task) -> None:
        self._tasks.put(task)

    def _work(self) -> None:
        while True:
            task = self._tasks.get()
            if task is None:
                return
            _safely(task, ())

    def stop(self, timeout: float = 5.0) -> None:
        """End the threads once the tasks submitted so far are done."""
        for _ in self.threads:
            self._tasks.put(None)
        me = threading.current_thread()
        deadline = time.monotonic() + timeout
        for thread in self.threads:
            if thread is not me:
                thread.join(max(0.0, deadline - time.monotonic()))


class Lane:
    """One robot's share of a `CallPool`: at most `limit` of its tasks run at once, the others wait in order.
    `busy()` counts its tasks not finished yet (waiting or running); `wait_idle` waits for none."""

    def __init__(self, pool: CallPool, limit: int = ROBOT_CALLS) -> None:
        self.pool = pool
        self.limit = limit
        self._cond = threading.Condition()
        self._waiting: deque[Task] = deque()
        self._running = 0
        self._flying = 0  # calls in flight without a pool thread (`begin`), which `wait_idle` waits for too

    def submit(self, task: Task) -> None:
        with self._cond:
            if self._running >= self.limit:
                self._waiting.append(task)
                return
            self._running += 1
        self.pool.submit(lambda: self._run(task))

    def _run(self, task: Task) -> None:
        while True:
            _safely(task, ())
            with self._cond:
                if not self._waiting:
                    self._running -= 1
                    self._cond.notify_all()
                    return
                task = self._waiting.popleft()  # this thread takes the next one: its order is kept

    def begin(self) -> None:
        """A call of this robot is sent without a pool thread (the port answers it on its own thread): it counts
        as in flight (`busy`, `wait_idle`) until `end`, but takes no place of the `limit`."""
        with self._cond:
            self._flying += 1

    def pooled(self) -> int:
        """Its tasks on the pool, running or waiting (not the calls sent without a pool thread)."""
        with self._cond:
            return self._running + len(self._waiting)

    def end(self) -> None:
        with self._cond:
            self._flying -= 1
            if not self._flying:
                self._cond.notify_all()

    def busy(self) -> int:
        with self._cond:
            return self._running + len(self._waiting) + self._flying

    def wait_idle(self, timeout: float) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: self._running == 0 and not self._waiting and not self._flying, timeout)


class Shared:
    """The process's loop and call pool, and how many engines use them."""

    def __init__(self) -> None:
        self.loop = Loop()
        self.pool = CallPool()
        self.users = 0

    def stop(self) -> None:
        self.loop.stop()
        self.pool.stop()


_shared: Shared | None = None
_shared_lock = threading.Lock()


def acquire() -> Shared:
    """The process's loop and pool (started by the first engine that asks); `release()` once done with them."""
    global _shared
    with _shared_lock:
        if _shared is None:
            _shared = Shared()
        _shared.users += 1
        return _shared


def release(shared: Shared) -> None:
    """An engine is done with the loop and pool: the last one stops their threads."""
    global _shared
    with _shared_lock:
        shared.users -= 1
        if shared.users > 0 or _shared is not shared:
            return
        _shared = None
    shared.stop()
