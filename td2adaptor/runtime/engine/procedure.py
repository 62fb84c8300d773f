"""A procedure mission as a state machine driven by the engine's loop (loop.py), not a thread of its own.

A mission starts (`STARTING`: the run call), then is followed (`POLLING`: every `poll_period` a timer asks
the linked query), until the robot reports a terminal state, `mission_timeout` passes (the robot is asked to
cancel: `CANCELLING`, then it ends `failed`, `timeout`), `max_query_failures` queries in a row fail
(`unreachable`) or the node stops (`ENDED` without an event: the mission is left to the robot, and to the
ledger, so a restarted node follows it on). A cancel event wakes the mission at once: it asks the robot
(`CANCELLING`) and answers with a state event. A feedback event on every state change, exactly one terminal
event (the outbox and the `MissionTable` see to it).

Who does what: the loop's thread owns the machines (which missions run, their timers, whether a call is in
flight) and takes each step: a timer, a cancel event or the stop wakes a mission, and the loop decides what
it does next. A step that needs the robot hands its call to the robot's lane of the call pool; the pool
thread that made the call reads the answer and publishes what it says (the step's end: the mission's fields
belong to that thread until then, as they belong to the loop between calls), then hands the mission back to
the loop (a posted callback), which schedules the next step. So an answer is published without waiting for
the loop (the first feedback of an invoke crosses two threads: the bus's, the loop, the pool), and one step
of a mission runs at a time.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import Enum
from functools import partial
from typing import Any

from td2adaptor.model import Procedure
from td2adaptor.model.events import Kind
from td2adaptor.runtime.engine.context import RobotContext
from td2adaptor.runtime.engine.missions import Mission
from td2adaptor.runtime.loop import Timer
from td2adaptor.runtime.ros.port import Answered, PortError, StartResult
from td2adaptor.runtime.ros.procedures import ProcedureStatus, Reading, read
from td2adaptor.runtime.ros.words import INTERNAL, describe

log = logging.getLogger("td2adaptor.runtime")

DEFAULT_MISSION_PATH = ("state", "header", "id")


class Phase(Enum):
    STARTING = "starting"  # the run call is in flight
    POLLING = "polling"  # waiting for the next query, or querying
    CANCELLING = "cancelling"  # a cancel call is in flight (a cancel event's, or the timeout's)
    ENDED = "ended"  # terminal event published, or left to the robot at a stop


class Then(Enum):
    """What the loop does with a mission once the answer to its call is read and published."""

    NEXT = "next"  # a cancel that came meanwhile (or the stop) at once, else the next query in `poll_period`
    STEP = "step"  # the next step at once (the other cancels, the deadline, a query)
    END = "end"  # nothing: the mission ended


@dataclass(eq=False)
class Run:
    """One procedure mission's machine: its `Mission` (what the outbox numbers and the table holds) and what
    following it needs."""

    m: Mission
    held: threading.Event  # set once the machine is done with the mission (stopping waits for it)
    deadline: float
    phase: Phase = Phase.STARTING
    calling: bool = False  # a robot call of it is in flight: the answer, not a timer, moves it on
    timer: Timer | None = None  # the next query's
    failures: int = 0  # queries failed in a row
    cancels: deque[str | None] = field(default_factory=deque)  # cancel events taken, not carried out yet
    started: list[Callable[[], None]] = field(default_factory=list)  # to do once the run call is answered
    started_timer: Timer | None = None  # when `started` is done anyway (the run call takes long)


Reader = Callable[[Run, Any, "Exception | None"], Then]
#: a call sent without a waiting thread (`QuickCall`): `quick(on_done)` sends it and says whether it did
Quick = Callable[[Answered], bool]


class ProcedureRunner:
    """Follows one robot's procedure missions (see the module docstring). The public methods run on the loop's
    thread. Handed the robot's context (context.py), never the engine."""

    def __init__(self, ctx: RobotContext) -> None:
        self.ctx = ctx
        self._runs: dict[int, Run] = {}  # by id of the Mission (the loop's)

    # -- events (the loop) ---------------------------------------------------------------------------------

    def start(self, m: Mission, held: threading.Event) -> None:
        """Run a mission the engine admitted (its component claimed with `held`)."""
        run = self._add(m, held)
        timeout = self.ctx.config.call_timeout
        start = partial(self.ctx.port.start, m.component, m.action, m.payload, timeout)
        quick = self.ctx.quick
        fast = partial(quick.try_start, m.component, m.action, m.payload, timeout) if quick is not None else None
        self._call(run, Phase.STARTING, start, self._started, fast)

    def resume(self, m: Mission, held: threading.Event) -> None:
        """Follow on a mission the robot runs already (a restart of this node): its first query in a period."""
        run = self._add(m, held)
        run.phase = Phase.POLLING
        self._sleep(run)

    def poke(self, m: Mission) -> None:
        """A cancel event was handed to `m` (MissionTable.add_cancel): carry it out now, unless a call of the
        mission is in flight (then right after its answer)."""
        run = self._runs.get(id(m))
        if run is not None:
            self._wake(run)

    def when_started(self, m: Mission, do: Callable[[], None], within: float) -> bool:
        """Call `do` (on the loop) once the robot answered `m`'s run call, or in `within` seconds if it takes
        longer, when that call is in flight; False when it is not (nothing is done)."""
        run = self._runs.get(id(m))
        if run is None or run.phase is not Phase.STARTING or not run.calling:
            return False
        run.started.append(do)
        if run.started_timer is None:
            run.started_timer = self.ctx.loop.call_later(within, self._after_start, run)
        return True

    def stop(self) -> None:
        """The node stops: leave every mission to the robot (one with a call in flight once it is answered)."""
        for run in list(self._runs.values()):
            self._wake(run)

    # -- the machine (the loop) ----------------------------------------------------------------------------

    def _add(self, m: Mission, held: threading.Event) -> Run:
        run = Run(m, held, m.started + self.ctx.config.mission_timeout)
        self._runs[id(m)] = run
        return run

    def _call(
        self, run: Run, phase: Phase, call: Callable[[], Any], reader: Reader, quick: Quick | None = None
    ) -> None:
        """Make a robot call: sent from here when the port can do it without a waiting thread (`quick`), its
        answer read and published with `reader` on the port's thread; else on the lane, and the pool thread
        reads and publishes it. Then the mission is handed back to the loop."""
        run.phase, run.calling = phase, True

        def answered(value: Any, error: Exception | None) -> None:
            try:
                then = reader(run, value, error)
            except Exception:  # the last line of defence: report, never crash
                log.exception("mission %s failed internally", run.m.action)
                self.ctx.outbox.finish(run.m, ProcedureStatus("failed", message=INTERNAL, reason="call-failed"))
                then = Then.END
            self.ctx.loop.post(self._answered, run, then)

        if quick is not None and self.ctx.send_quick(quick, answered):
            return

        def task() -> None:
            try:
                value, error = call(), None
            except Exception as exc:  # noqa: BLE001 - handed to the reader, which reports it
                value, error = None, exc
            answered(value, error)

        self.ctx.lane.submit(task)

    def _answered(self, run: Run, then: Then) -> None:
        run.calling = False
        self._after_start(run)
        if then is Then.END:
            self._leave(run)
        elif then is Then.STEP or self.ctx.stopping.is_set() or run.m.cancels:
            self._wake(run)
        else:
            self._sleep(run)

    def _after_start(self, run: Run) -> None:
        """What waited for the run call's answer (a refusal that names the mission id): now."""
        if run.started_timer is not None:
            run.started_timer.cancel()
            run.started_timer = None
        waiting, run.started = run.started, []
        for do in waiting:
            try:
                do()
            except Exception:  # one of them must not keep the mission from going on
                log.exception("after %s started", run.m.action)

    def _sleep(self, run: Run) -> None:
        """Wait for the next query: `poll_period`, or what is left until the deadline."""
        wait = max(0.0, min(self.ctx.config.poll_period, run.deadline - self.ctx.clock()))
        run.timer = self.ctx.loop.call_later(wait, self._wake, run)

    def _wake(self, run: Run) -> None:
        """A timer, a cancel event or the stop: the next step, unless a call is in flight or it ended."""
        if run.calling or run.phase is Phase.ENDED:
            return
        if run.timer is not None:
            run.timer.cancel()
            run.timer = None
        try:
            self._step(run)
        except Exception:  # the last line of defence: report, never crash
            log.exception("mission %s failed internally", run.m.action)
            self.ctx.outbox.finish(run.m, ProcedureStatus("failed", message=INTERNAL, reason="call-failed"))
            self._leave(run)

    def _step(self, run: Run) -> None:
        """What a woken mission does next: leave (stopping), carry out a cancel, give up (deadline), or query."""
        m, proc, cfg = run.m, run.m.procedure, self.ctx.config
        if self.ctx.stopping.is_set():
            log.info("stopping: no longer following %s mission %s", m.action, m.mission_id)
            self._leave(run)
            return
        run.cancels.extend(self.ctx.missions.take_cancels(m))
        mid = m.mission_id if m.mission_id is not None else -1
        while run.cancels:
            correlation = run.cancels.popleft()
            if proc.cancel is None:
                self._error("unsupported", f"{m.action} has no cancel action", Kind.INVOKE, m.action, correlation, m)
                continue
            ask = partial(answer, self.ctx.port.cancel, m.component, proc.cancel, mid, cfg.call_timeout)
            fast = self._quick("try_cancel", m.component, proc.cancel, mid, answered=True)
            self._call(run, Phase.CANCELLING, ask, partial(self._cancelled, correlation), fast)
            return
        if self.ctx.clock() >= run.deadline:
            if proc.cancel is not None and m.mission_id is not None:  # ask the robot to stop it, then give up
                ask = partial(self.ctx.port.cancel, m.component, proc.cancel, m.mission_id, cfg.call_timeout)
                fast = self._quick("try_cancel", m.component, proc.cancel, m.mission_id, answered=False)
                self._call(run, Phase.CANCELLING, ask, self._timed_out, fast)
                return
            self._timed_out(run, None, None)
            self._leave(run)
            return
        assert proc.query is not None
        ask = partial(answer, self.ctx.port.query, m.component, proc.query, mid, cfg.call_timeout)
        self._call(run, Phase.POLLING, ask, self._queried, self._quick("try_query", m.component, proc.query, mid))

    def _quick(self, method: str, component: str, action: str, mid: int, *, answered: bool = True) -> Quick | None:
        """A query's or cancel's call without a waiting thread (`QuickCall`), or None when the port has none;
        `answered`: a response the port raised with (the robot said `error`) is the answer, as `answer` reads it."""
        quick = self.ctx.quick
        if quick is None:
            return None
        send = getattr(quick, method)
        timeout = self.ctx.config.call_timeout

        def fast(on_done: Answered) -> bool:
            return bool(send(component, action, mid, timeout, answering(on_done) if answered else on_done))

        return fast

    def _leave(self, run: Run) -> None:
        """The machine is done with the mission (ended, or left to the robot at a stop)."""
        if run.phase is Phase.ENDED:
            return
        run.phase = Phase.ENDED
        if run.timer is not None:
            run.timer.cancel()
            run.timer = None
        self._runs.pop(id(run.m), None)
        self.ctx.missions.release(run.held)
        run.held.set()

    # -- readers: an answer, read and published (the pool thread that made the call) --------------------------

    def _started(self, run: Run, value: Any, error: Exception | None) -> Then:
        m, proc = run.m, run.m.procedure
        refused = False
        if isinstance(error, PortError):
            if error.response is None:  # no answer: we cannot know whether it runs
                log.warning("%s: failed (%s): %s", m.action, error.reason, describe(error))
                return self._finish(run, ProcedureStatus("failed", message=describe(error), reason=error.reason))
            value, refused = StartResult(error.response, None), True  # the robot answered, and refused
        elif error is not None:
            log.warning("%s: failed: %s", m.action, describe(error))
            return self._finish(run, ProcedureStatus("failed", message=describe(error), reason="call-failed"))
        started: StartResult = value
        reading = read(started.response, proc, "run", DEFAULT_MISSION_PATH)
        status = reading.status or ProcedureStatus("running", message="started")
        if reading.unmapped is not None:
            log.warning("%s: state value %r is not mapped: taken as started", m.action, reading.unmapped)
        if status.state != "failed" and (refused or _says_error(started.response)):
            status = ProcedureStatus("failed", status.result, status.message or _message(started.response))
        if status.state == "failed":  # refused by the robot: the id in its answer is not ours
            why = "answered with an error" if refused or _says_error(started.response) else "reported it failed"
            log.warning("%s: rejected: the robot %s: %s", m.action, why, status.message or "(no message)")
            rejected = ProcedureStatus("failed", status.result, status.message, status.last_event, "rejected")
            return self._finish(run, rejected)
        m.mission_id = started.mission_id if started.mission_id is not None else status.mission_id
        if m.mission_id is None:
            log.warning("%s returned no mission id; following mission -1 (the robot's last one)", m.action)
        if status.terminal:
            return self._finish(run, status)
        self.ctx.outbox.feedback(m, status, terminal=False)
        if proc.query is None:
            message = "started; no query action links to this procedure"
            return self._finish(run, ProcedureStatus("finished", message=message))
        run.phase = Phase.POLLING
        return Then.NEXT

    def _queried(self, run: Run, value: Any, error: Exception | None) -> Then:
        m, cfg = run.m, self.ctx.config
        mid = m.mission_id if m.mission_id is not None else -1
        reading, error = _read(value, error, m.procedure, "query")  # an answer that cannot be read: a failed query
        if reading is None:
            assert error is not None
            run.failures += 1
            log.warning("query %d of %s mission %s failed: %s", run.failures, m.action, mid, describe(error))
            if run.failures >= cfg.max_query_failures:
                message = f"the robot did not answer {run.failures} queries: {describe(error)}"
                return self._finish(run, ProcedureStatus("failed", message=message, reason="unreachable"))
            return Then.NEXT
        run.failures = 0
        current = reading.status
        if current is None:  # validate refuses such a query (ROS445); an unmapped value is no news
            log.warning("query of %s mission %s: no state in the answer (%r)", m.action, mid, reading.unmapped)
        elif current.terminal:
            if current.state == "failed":
                log.warning("%s mission %s: the robot reports it failed: %s", m.action, mid, current.message)
            return self._finish(run, current)
        elif current.state != m.state:
            self.ctx.outbox.feedback(m, current, terminal=False)
        return Then.NEXT

    def _cancelled(self, correlation: str | None, run: Run, value: Any, error: Exception | None) -> Then:
        """A cancel event's call answered: a state event for it, the mission's end if the robot says so."""
        m, proc = run.m, run.m.procedure
        mid = m.mission_id if m.mission_id is not None else -1
        run.phase = Phase.POLLING
        reading, error = _read(value, error, proc, "cancel")  # an answer that cannot be read: a failed cancel
        if reading is None:
            assert proc.cancel is not None and error is not None
            message = f"cancelling {m.action} mission {mid} failed: {describe(error)}"
            self._error("call-failed", message, Kind.CANCEL, proc.cancel, correlation, m)
            return Then.STEP  # the other cancels, then the deadline and the query, as if woken
        status = reading.status or requested(m.state)
        self.ctx.outbox.state(m.action, status, correlation, m.mission_id)
        if status.terminal:
            return self._finish(run, status)
        if status.state != m.state:
            self.ctx.outbox.feedback(m, status, terminal=False)
        return Then.STEP

    def _timed_out(self, run: Run, value: Any, error: Exception | None) -> Then:
        """The mission timeout passed (and the robot was asked to cancel it, when it could be named)."""
        m = run.m
        if error is not None:
            log.warning("could not cancel timed-out %s mission %s: %s", m.action, m.mission_id, describe(error))
        message = f"no terminal state within the mission timeout of {self.ctx.config.mission_timeout:g} s"
        last = f" (last state: {m.state})" if m.state else ""
        return self._finish(run, ProcedureStatus("failed", message=message + last, reason="timeout"))

    def _finish(self, run: Run, status: ProcedureStatus) -> Then:
        self.ctx.outbox.finish(run.m, status)
        return Then.END

    def _error(self, code: str, message: str, kind: Kind, affordance: str, correlation: str | None, m: Mission) -> None:
        """An error event answering a cancel event of mission `m`, on the topic of the `kind` event of `affordance`."""
        topic = self.ctx.topic(kind, affordance)
        self.ctx.outbox.error(
            code, message, topic=topic, affordance=affordance, correlation=correlation, mission=m.mission_id
        )


def _read(
    value: Any, error: Exception | None, procedure: Procedure, kind: str
) -> tuple[Reading | None, Exception | None]:
    """A query's or cancel's answer read (None and why when the call failed or its answer cannot be read)."""
    if error is not None:
        return None, error
    try:
        return read(value, procedure, kind, DEFAULT_MISSION_PATH), None
    except Exception as exc:  # noqa: BLE001 - handed to the caller, which reports it
        return None, exc


def answer(
    call: Callable[[str, str, int, float], Mapping[str, Any]], component: str, action: str, mission: int, timeout: float
) -> Mapping[str, Any]:
    """The robot's response to a query or cancel, also when the port raised because it says `error`."""
    try:
        return call(component, action, mission, timeout)
    except PortError as exc:
        if exc.response is None:
            raise
        return exc.response


def answering(on_done: Answered) -> Answered:
    """`on_done` for a query or cancel sent without a waiting thread, told the robot's response as the answer
    when the port raised with one (the robot said `error`), as `answer` reads a call that waited."""

    def told(value: Any, error: PortError | None) -> None:
        if error is not None and error.response is not None:
            value, error = error.response, None
        on_done(value, error)

    return told


def requested(state: str | None) -> ProcedureStatus:
    """The answer to a cancel whose response carries no state: asked, the mission's end will tell."""
    return ProcedureStatus(state or "running", message="cancel requested")


def _message(response: Mapping[str, Any]) -> str:
    """The robot's words in a response without a procedure state (std_srvs' `message`)."""
    text = response.get("message")
    return text if isinstance(text, str) else ""


def _says_error(response: Mapping[str, Any]) -> bool:
    result = response.get("result")
    return isinstance(result, Mapping) and str(result.get("result", "")).lower() == "error"
