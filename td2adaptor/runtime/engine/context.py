"""What the engine's mission runners share of one robot, in one object: built once by the engine as it starts.

`ProcedureRunner` (procedure.py) and `GoalRunner` (goals.py) follow a robot's missions with the same
collaborators: the robot's port, its settings, its `MissionTable` and `Outbox`, the process's loop, the robot's
lane of the call pool, the flag that says the engine stops, and the clock. Handing them this rather than the
`Engine` keeps the runners from reaching into it; handing it rather than eight arguments keeps the two alike.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from td2adaptor.model.events import Kind
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.missions import MissionTable
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.loop import Lane, Loop
from td2adaptor.runtime.ros.port import Answered, PortError, PortTimeout, QuickCall, RobotPort


@dataclass(frozen=True)
class RobotContext:
    """One robot's collaborators (see the module docstring)."""

    port: RobotPort
    config: RuntimeConfig
    missions: MissionTable
    outbox: Outbox
    loop: Loop
    lane: Lane
    stopping: threading.Event
    clock: Callable[[], float]
    #: before a ROS action goal is sent: `gate(go)` calls `go(True)` once it may be, `go(False)` if it must not
    #: (Engine.gate; None: at once)
    gate: Callable[[Callable[[bool], None]], None] | None = None
    #: the port, when it can make calls without a waiting thread (`QuickCall`: ROS 2's generated packages)
    quick: QuickCall | None = None

    def send_quick(self, send: Callable[[Answered], bool], told: Answered) -> bool:
        """Send a call without a waiting thread: `send(on_done)` (a `QuickCall` method) says whether it did;
        `told(answer, error)` is then called once, where the port answers, or on the loop with `PortTimeout` if
        no answer came `QUICK_MARGIN` seconds past the call timeout (the port's own deadline is the call
        timeout: this only guards against a port that never answers). The call counts on the robot's lane
        (`busy`, `wait_idle`) until told.

        Only one call at a time: while another quick call of the process or a call of the robot on the pool is
        in flight, False (the caller uses the pool). The port's thread that tells the answer also takes the
        next response; with calls overlapping, a pool thread that publishes one answer while that thread takes
        the next was faster (8 in flight: about 20 % more answers a second). One at a time, no thread waits."""
        if _flying.count(self.loop) or self.lane.pooled():  # calls overlap: the pool's turn
            return False
        once = _Once(told, self.lane, self.loop)
        self.lane.begin()
        _flying.add(self.loop, 1)
        if not send(once.tell):
            _flying.add(self.loop, -1)
            self.lane.end()
            return False
        limit = self.config.call_timeout + QUICK_MARGIN
        timer = self.loop.call_later(limit, once.tell, None, PortTimeout(f"no answer within {limit:g} s"))
        once.timer = timer
        if once.done:
            timer.cancel()
        return True

    def topic(self, kind: Kind, affordance: str, component: str | None = None) -> str:
        """The topic of the robot's `kind` event of `affordance` ("" when the robot has none)."""
        for spec in self.outbox.catalog.specs:
            if (
                spec.kind is kind
                and spec.affordance == affordance
                and (component is None or spec.component == component)
            ):
                return spec.topic(self.config.robot, self.config.topic_root)
        return ""


#: seconds past the call timeout after which the engine stops waiting for a call sent without a waiting thread
#: (the port's own deadline is the call timeout; the ROS 1 bridge's child, wait_timeout + timeout)
QUICK_MARGIN = 15.0


class _Flying:
    """The quick calls in flight of each loop (a process's engines share one): a loop that stopped with one
    never answered is forgotten with it, and the next loop starts from none."""

    def __init__(self) -> None:
        self._counts: weakref.WeakKeyDictionary[Loop, int] = weakref.WeakKeyDictionary()
        self._lock = threading.Lock()

    def count(self, loop: Loop) -> int:
        return self._counts.get(loop, 0)

    def add(self, loop: Loop, step: int) -> None:
        with self._lock:
            self._counts[loop] = self._counts.get(loop, 0) + step


_flying = _Flying()


class _Once:
    """A quick call's answer or its guard's timeout, whichever comes first, told once; the lane told it ended."""

    def __init__(self, told: Answered, lane: Lane, loop: Loop) -> None:
        self.told = told
        self.lane = lane
        self.loop = loop
        self.done = False
        self.timer: Any = None
        self._lock = threading.Lock()

    def tell(self, answer: Any, error: PortError | None) -> None:
        with self._lock:
            if self.done:
                return
            self.done = True
        if self.timer is not None:
            self.timer.cancel()
        _flying.add(self.loop, -1)
        try:
            self.told(answer, error)
        finally:
            self.lane.end()
