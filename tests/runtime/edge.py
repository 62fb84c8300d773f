"""Shared by the edge-node tests: waiting, feedback bookkeeping, a `td2adaptor run` child process."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from td2adaptor.runtime.bus.bus import Bus
from td2adaptor.runtime.bus.thingbus import ThingBus
from td2adaptor.runtime.engine.engine import Engine
from tests.conftest import REPO

#: a Python class name followed by a colon, as `f"{type(exc).__name__}: {exc}"` writes it: never in a user's words
CLASS_NAME = re.compile(
    r"\b(?:[A-Z][a-z0-9]*)+(?:Error|Exception|Unavailable|Timeout|Failed|Rejected|Aborted|Canceled|Message|Name):"
)

Event = tuple[str, dict[str, Any]]


def bus_of(engine: Engine) -> Bus:
    """The engine's own bus, under the WoT adapter `serve` wraps it in."""
    bus = engine.bus
    return bus.bus if isinstance(bus, ThingBus) else bus


def stretched(bound: float) -> float:
    """A time `bound` the issue sets (a robot served within 2 s of its appearance), stretched on a machine busier
    than its cores (load average above twice their number, as a loaded CI run with `-n 2` can be): every step is
    then a process's turn on a core (measured: 0.4-1.1 s at load 8-12, 1.8-3 s at 26). The figures under no
    load are the benches' and docs/fleet.md's."""
    busy = os.getloadavg()[0] / (2 * (os.cpu_count() or 1))
    return bound * max(1.0, busy)


def until(predicate: Callable[[], bool], timeout: float, period: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period)
    return predicate()


def feedback(events: Sequence[Event], correlation: str) -> list[dict[str, Any]]:
    return [e for _, e in events if e.get("type") == "feedback" and e.get("correlation") == correlation]


def check_mission(events: Sequence[Event], correlation: str, states: Sequence[str]) -> list[dict[str, Any]]:
    """The mission's feedback: exactly `states`, numbered 1.., one terminal event (the last), one mission id."""
    fb = feedback(events, correlation)
    unique = {e["id"]: e for e in fb}  # a QoS 1 redelivery repeats an event, never adds one
    fb = sorted(unique.values(), key=lambda e: e["payload"]["seq"])
    assert [e["payload"]["state"] for e in fb] == list(states), [e["payload"] for e in fb]
    assert [e["payload"]["seq"] for e in fb] == list(range(1, len(states) + 1))
    assert [e["payload"]["terminal"] for e in fb] == [False] * (len(states) - 1) + [True]
    assert len({e.get("mission") for e in fb}) == 1
    return fb


class RunProcess:
    """`td2adaptor run ...` in a child process; its stderr in a file (read on failure)."""

    def __init__(
        self,
        args: Sequence[str],
        env: dict[str, str] | None = None,
        command: Sequence[str] | None = None,
        new_session: bool = False,
    ) -> None:
        self.log = tempfile.NamedTemporaryFile(prefix="td2adaptor-run-", suffix=".log", delete=False)
        self.proc = subprocess.Popen(
            [*(command or [sys.executable, "-m", "td2adaptor", "run"]), *args],
            cwd=REPO,
            env=env if env is not None else dict(os.environ),
            stdout=subprocess.DEVNULL,
            stderr=self.log,
            start_new_session=new_session,  # its own process group, as a launch system starts it
        )

    def output(self) -> str:
        return Path(self.log.name).read_text(encoding="utf-8", errors="replace")

    def wait_ready(self, timeout: float = 60.0) -> None:
        ok = until(lambda: "SIGINT/SIGTERM stops" in self.output() or self.proc.poll() is not None, timeout, 0.05)
        assert ok and self.proc.poll() is None, f"td2adaptor run did not start:\n{self.output()}"

    def terminate(self, sig: int = signal.SIGTERM, timeout: float = 20.0, group: bool = False) -> int:
        if self.proc.poll() is None:
            if group:  # every process of the group, children included (Ctrl-C, roslaunch, systemd)
                os.killpg(self.proc.pid, sig)
            else:
                self.proc.send_signal(sig)
        try:
            return self.proc.wait(timeout)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait(5)

    def close(self) -> None:
        self.terminate()
        self.log.close()
        os.unlink(self.log.name)


class Recorder:
    """An application on a local bus that records (topic, event) under its patterns and sends raw bytes."""

    def __init__(self, broker: Any, patterns: Sequence[str], client_id: str = "recorder") -> None:
        from td2adaptor.runtime import LocalBus

        self.events: list[Event] = []
        self.cond = threading.Condition()
        self.bus = LocalBus(broker, client_id)
        for pattern in patterns:
            self.bus.subscribe(pattern, self._on)
        self.bus.connect()

    def _on(self, msg: Any) -> None:
        data = json.loads(msg.payload)
        with self.cond:
            self.events.append((msg.topic, data))
            self.cond.notify_all()

    def send(self, topic: str, payload: bytes) -> None:
        self.bus.publish(topic, payload)

    def wait(self, predicate: Callable[[list[Event]], bool], timeout: float = 10.0) -> list[Event]:
        with self.cond:
            assert self.cond.wait_for(lambda: predicate(self.events), timeout), f"timed out: {self.events[-3:]}"
            return list(self.events)

    def of(self, kind: str) -> list[dict[str, Any]]:
        with self.cond:
            return [e for _, e in self.events if e.get("type") == kind]

    def close(self) -> None:
        self.bus.close()


class GoalEvents:
    """A `GoalListener` (runtime/ros/port.py) that records what a port tells of one goal, for a test to wait on."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.told: list[tuple[str, Any]] = []  # (what, value) in the order told
        self.threads: set[str] = set()  # the threads that told them

    def _tell(self, what: str, value: Any) -> None:
        with self.cond:
            self.told.append((what, value))
            self.threads.add(threading.current_thread().name)
            self.cond.notify_all()

    def on_accepted(self, goal: str) -> None:
        self._tell("accepted", goal)

    def on_status(self, status: str) -> None:
        self._tell("status", status)

    def on_feedback(self, message: Any) -> None:
        self._tell("feedback", message)

    def on_done(self, end: Any) -> None:
        self._tell("done", end)

    def end(self, timeout: float) -> Any:
        """The goal's end (a GoalEnd), once told within `timeout` seconds; None otherwise."""
        with self.cond:
            self.cond.wait_for(lambda: any(what == "done" for what, _ in self.told), timeout)
            return next((value for what, value in self.told if what == "done"), None)


def rejects(port: Any, component: str, action: str, payload: dict[str, Any], timeout: float = 2.0) -> bool:
    """Whether a goal of `payload` sent through `port` is rejected by its action server within `timeout` (an
    answered goal: the server is there and answers us)."""
    events = GoalEvents()
    try:
        port.start_goal(component, action, payload, 1.0, events)
    except Exception:  # noqa: BLE001 - not there yet
        return False
    end = events.end(timeout)
    if end is not None and end.status not in ("rejected", "lost"):
        raise AssertionError(f"a goal of {payload} was not rejected: {end}")
    return end is not None and end.status == "rejected"
