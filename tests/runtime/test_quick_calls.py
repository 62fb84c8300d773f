"""Calls sent without a waiting thread (`RobotContext.send_quick`): one at a time, and never left unanswered.

The port side here is a callable that keeps what it was handed, so the test decides when (and whether) the
"ROS side" answers; the loop, the call pool and the robot's lane are the engine's own.
"""

from __future__ import annotations

import threading
import time
from typing import Any, cast

import pytest

from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine import context
from td2adaptor.runtime.engine.context import RobotContext
from td2adaptor.runtime.loop import Lane, acquire, release
from td2adaptor.runtime.ros.port import Answered, PortError, PortTimeout


class Port:
    """Takes calls and answers them when told to (`answer`), from the test's thread."""

    def __init__(self) -> None:
        self.sent: list[Answered] = []

    def __call__(self, on_done: Answered) -> bool:
        self.sent.append(on_done)
        return True


class Told:
    def __init__(self) -> None:
        self.calls: list[tuple[Any, PortError | None, str]] = []
        self.done = threading.Event()

    def __call__(self, answer: Any, error: PortError | None) -> None:
        self.calls.append((answer, error, threading.current_thread().name))
        self.done.set()


@pytest.fixture
def ctx() -> Any:
    shared = acquire()
    lane = Lane(shared.pool)
    config = RuntimeConfig(robot="quick", call_timeout=0.2)
    nothing = cast(Any, None)
    yield RobotContext(nothing, config, nothing, nothing, shared.loop, lane, threading.Event(), time.monotonic)
    release(shared)


def test_only_one_call_at_a_time_is_sent_without_a_thread(ctx: RobotContext) -> None:
    """While a quick call is in flight the next is refused (the caller uses the pool: with calls overlapping,
    a pool thread publishing one answer while the reader takes the next answers more a second)."""
    port, first, second, third = Port(), Told(), Told(), Told()
    assert ctx.loop.call(lambda: ctx.send_quick(port, first)) is True
    assert ctx.lane.busy() == 1
    assert ctx.loop.call(lambda: ctx.send_quick(port, second)) is False
    assert len(port.sent) == 1  # the refused one was not sent
    port.sent[0]({"state": "running"}, None)
    assert first.calls == [({"state": "running"}, None, "MainThread")] and ctx.lane.wait_idle(1.0)
    assert ctx.loop.call(lambda: ctx.send_quick(port, third)) is True
    port.sent[1]({}, None)
    assert third.done.is_set() and not second.calls


def test_a_call_its_port_never_answers_is_answered_once_by_the_loop(
    ctx: RobotContext, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No answer by call_timeout + QUICK_MARGIN: told PortTimeout on the loop, and a late answer is dropped."""
    monkeypatch.setattr(context, "QUICK_MARGIN", 0.1)
    port, told = Port(), Told()
    begin = time.monotonic()
    assert ctx.loop.call(lambda: ctx.send_quick(port, told)) is True
    assert told.done.wait(5.0)
    assert 0.25 <= time.monotonic() - begin < 4.0
    port.sent[0]({"late": True}, None)
    assert len(told.calls) == 1
    answer, error, thread = told.calls[0]
    assert answer is None and isinstance(error, PortTimeout) and thread == "td2adaptor-engine"
    assert ctx.lane.wait_idle(1.0)
    again = Port()
    assert ctx.loop.call(lambda: ctx.send_quick(again, Told())) is True  # the process may send again
    again.sent[0]({}, None)
