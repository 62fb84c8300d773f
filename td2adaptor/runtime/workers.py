"""Threads kept for the next task: the edge node's per-goal followers without a thread start on the hot path.

Starting a thread blocks the starter until the new thread has run (CPython's `Thread.start` waits for it):
two hand-overs of the interpreter lock, each as long as a busy thread keeps it (up to the switch interval,
5 ms). A task given to an idle worker only wakes that worker; a new thread is started only when none is idle.
Workers wait for a task for `idle_timeout` seconds and then end. Not concurrent.futures' ThreadPoolExecutor:
its threads live until shutdown, a bound on them makes a long task wait for another one to end, and the
interpreter joins them at exit (a follower of a goal nobody closed would hold the exit); these are daemon
threads. Standard library only (the ROS 1 bridge runs the port under a ROS 1 interpreter).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable


class Workers:
    """Run tasks in threads of their own, reusing threads that finished theirs (no upper bound: a task that
    waits long, like following a goal, must never wait for another one to end)."""

    def __init__(self, name: str, idle_timeout: float = 30.0) -> None:
        self.name = name
        self.idle_timeout = idle_timeout
        self._cond = threading.Condition()
        self._tasks: deque[Callable[[], None]] = deque()
        self._idle = 0  # workers waiting for a task that no task was given to yet
        self._started = 0

    def submit(self, task: Callable[[], None]) -> None:
        """Run `task()` in a worker thread (an exception it raises is its own business: it must not raise)."""
        with self._cond:
            if self._idle > 0:
                self._idle -= 1
                self._tasks.append(task)
                self._cond.notify()
                return
            self._started += 1
            number = self._started
        thread = threading.Thread(target=self._work, args=(task,), name=f"{self.name}-{number}", daemon=True)
        thread.start()

    def _work(self, task: Callable[[], None]) -> None:
        while True:
            try:
                task()
            except Exception:  # noqa: BLE001, S110 - tasks report their own failures; the worker lives on
                pass
            with self._cond:
                self._idle += 1
                if not self._cond.wait_for(lambda: bool(self._tasks), self.idle_timeout):
                    self._idle -= 1  # nobody gave us a task: no task was counted against us either
                    return
                task = self._tasks.popleft()
