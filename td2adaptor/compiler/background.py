"""Run one independent stage in a forked child while the parent goes on (the CLI's two cores).

Used for the JSON-LD stage, which is as slow as everything else in `validate` together (pyld's import alone
is ~70 ms) and shares nothing with the schema checks. Only forks when it is safe: POSIX, a single thread,
not disabled by `TD2ADAPTOR_NO_FORK`. Whatever goes wrong in the child (death, an exception, an unpicklable
result) makes `result()` run the stage in the parent instead, so the outcome never depends on forking.
"""

from __future__ import annotations

import os
import pickle
import signal
import threading
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")


class Background(Generic[T]):
    def __init__(self, fn: Callable[[], T], *, enabled: bool = True) -> None:
        self._fn = fn
        self._pid: int | None = None
        self._fd: int | None = None
        if not (enabled and hasattr(os, "fork") and threading.active_count() == 1):
            return
        if os.environ.get("TD2ADAPTOR_NO_FORK"):
            return
        read_fd, write_fd = os.pipe()
        pid = os.fork()
        if pid == 0:  # child: compute, send, leave without running any parent cleanup
            os.close(read_fd)
            try:
                payload = pickle.dumps(("ok", fn()), protocol=pickle.HIGHEST_PROTOCOL)
            except BaseException:  # noqa: BLE001 - any failure: the parent recomputes
                payload = pickle.dumps(("failed", None))
            with os.fdopen(write_fd, "wb") as fh:
                fh.write(payload)
            os._exit(0)
        os.close(write_fd)
        self._pid, self._fd = pid, read_fd

    def result(self) -> T:
        """The stage's value: from the child if it delivered one, else computed here."""
        if self._pid is None or self._fd is None:
            return self._fn()
        with os.fdopen(self._fd, "rb") as fh:
            data = fh.read()
        os.waitpid(self._pid, 0)
        self._pid = self._fd = None
        try:
            status, value = pickle.loads(data)
        except Exception:  # noqa: BLE001 - truncated or empty: the child died
            return self._fn()
        return value if status == "ok" else self._fn()

    def cancel(self) -> None:
        """The value is not needed after all: stop the child."""
        if self._pid is None:
            return
        try:
            os.kill(self._pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        os.waitpid(self._pid, 0)
        if self._fd is not None:
            os.close(self._fd)
        self._pid = self._fd = None
