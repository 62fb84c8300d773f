"""The engine's side of TD actions bound to ROS actions: a goal is a mission, a state machine driven by the port.

An invoke sends the goal (one mission per component at a time, as for procedures). Once the server accepts,
a feedback event says so (`queued`, `result: accepted`, with the goal id); then every ROS feedback message
becomes one feedback event (`running`, `result` `executing` or `canceling`, the message in `feedback`), in
order, or, with `feedback_period` > 0, at most one per period carrying the latest message; then exactly one
terminal event: `finished` (succeeded), `cancelled` (canceled) or `failed` (aborted: reason `aborted`;
refused: `rejected`; no end within `mission_timeout`: `timeout`; the action server gone (the port says the
goal is `lost`: on ROS 2 after `action_server_timeout` of silence; through the ROS 1 bridge also when the
bridge dies): `unreachable`), with the server's result in `output` and its status word in `result`. A cancel
event asks the server to cancel the goal followed and is answered with a state event once the server
answered (the terminal feedback follows when the server ends the goal); a query answers with the goal's
current state, or with the end of the last goal (of an earlier one, or of one the last run of the node saw end: as
the ledger recorded its terminal event, while it keeps it). Every decision that fails a goal is logged. A goal the last
run of the node (or the robot's last owner in a shared fleet) left in flight is followed on by its id
(`rejoin`, when the port can: `GoalRejoin`): no `queued` event again, its feedback numbered on from the
ledger's, its real end; lost (the server does not know it, or is gone), it ends `failed` with words that say
what happened to the node first.

No thread waits for a goal. The port tells what happens to it through a `GoalListener` (ros/port.py), from
the ROS client library's threads, one call at a time per goal and in order, and each is handled right there
(ROS 2: in the executor's thread; the ROS 1 bridge: its reader's), under the goal's lock: the `queued`,
`running` and terminal events go out without a hand-off to the engine's loop, so the first feedback waits
neither for the loop to wake (a hand-off costs up to a switch interval of the interpreter lock while the
executor keeps it busy) nor for other work queued on it. The goal's machine (`Chase`) is shared by those calls
and the loop's own steps: its timers (the mission timeout, the feedback held back by `feedback_period`), a
query's or cancel's look at it, stopping. The lock keeps a goal's events numbered in order and none after its
terminal one: whoever ends the goal publishes that one under the lock and marks the goal ended with it, and
every other step looks at that mark first. The mission table, the ledger and the outbox are safe from any
thread. A goal is started on the loop itself when the port can do so without waiting (`QuickGoalStart`: ROS
2's generated `start_X` returns at once), else on the robot's lane of the call pool; the other calls into the
robot's side (cancel, forget) go to the lane, and a cancel's answer is posted back to the loop. The generated
package keeps the goal's feedback (one buffer) and tells it in order.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from td2adaptor.model.events import GOAL_WORDS, TERMINAL_STATES, EventSpec, Kind
from td2adaptor.runtime.engine.context import RobotContext
from td2adaptor.runtime.engine.missions import Mission
from td2adaptor.runtime.loop import Timer
from td2adaptor.runtime.ros.port import GoalEnd, GoalPort, GoalRejoin, PortCallFailed, PortError, QuickGoalStart
from td2adaptor.runtime.ros.procedures import ProcedureStatus
from td2adaptor.runtime.ros.words import INTERNAL, describe

log = logging.getLogger("td2adaptor.runtime")

#: ROS goal status → procedure state
_STATES = {
    "unknown": "queued",
    "pending": "queued",
    "accepted": "queued",
    "executing": "running",
    "canceling": "running",
    "succeeded": "finished",
    "canceled": "cancelled",
    "aborted": "failed",
    "rejected": "failed",
    "lost": "failed",
}
#: why a goal failed, by its status word
_REASONS = {"aborted": "aborted", "rejected": "rejected", "lost": "unreachable"}
_ENDS = {
    "succeeded": "the goal succeeded",
    "canceled": "the goal was canceled",
    "aborted": "the robot aborted the goal",
    "rejected": "the action server rejected the goal",
    "lost": "the goal was lost",
}


def goal_status(word: str, done: bool, message: str = "") -> ProcedureStatus:
    """A goal's status word as a procedure state (`done`: the goal ended); the word is kept as `result`, the
    server's words (or ours, when it said nothing) as `message`."""
    state = _STATES.get(word, "running")
    if done and state not in ("finished", "cancelled", "failed"):
        return ProcedureStatus("failed", word, f"the goal ended with status {word}", reason="robot-error")
    reason = _REASONS.get(word, "robot-error") if state == "failed" else None
    message = message or (_ENDS.get(word, "") if done else "")
    return ProcedureStatus(state, word if word in GOAL_WORDS else "unknown", message, reason=reason)


def _running_word(word: str) -> str:
    """The status word a `running` feedback event carries: the goal's own while it runs (`canceling`), else
    `executing`. A server sends feedback only while it executes the goal, but the goal's status may already say
    how it ended: that word belongs to the terminal event alone."""
    return word if _STATES.get(word) == "running" else "executing"


@dataclass(frozen=True)
class _Ended:
    goal: str
    status: ProcedureStatus


@dataclass(eq=False)
class Chase:
    """One goal's machine (the loop's; see the module docstring)."""

    m: Mission
    held: threading.Event  # set once the machine is done with the mission (stopping waits for it)
    # held while the goal's state changes and its events are published: by the port's thread (acceptance,
    # status, feedback) and by the loop (the rest)
    lock: threading.RLock = field(default_factory=threading.RLock)
    goal: str | None = None  # the port's id of the goal, once start_goal returned or the server accepted
    accepted: bool = False
    status: str = "unknown"  # the latest status the port told
    ended: bool = False  # the terminal event is published, or the goal was left to the robot
    cancel_when_sent: bool = False  # given up before start_goal returned: cancel the goal once it has an id
    deadline: Timer | None = None  # the mission timeout's
    kept: tuple[Any, ...] = ()  # the latest feedback message held back by feedback_period (one or none)
    sent: float = float("-inf")  # when the last feedback event went out (feedback_period)
    flush: Timer | None = None  # when the held message goes out
    #: a goal the last run (or owner) left, followed on by its id (`GoalRunner.rejoin`): the start of the words
    #: of its end if it is lost (what happened to the robot's edge node), else None
    rejoined: str | None = None


class _Told:
    """The listener of one goal: what the port tells is handled in the port's thread, under the goal's lock (see
    the module docstring)."""

    def __init__(self, runner: GoalRunner, chase: Chase) -> None:
        self.runner = runner
        self.chase = chase

    def on_accepted(self, goal: str) -> None:
        self.runner._accepted(self.chase, goal)

    def on_status(self, status: str) -> None:
        self.runner._status(self.chase, status)

    def on_feedback(self, message: Any) -> None:
        self.runner._feedback(self.chase, message)

    def on_done(self, end: GoalEnd) -> None:
        self.runner._done(self.chase, end)


class GoalRunner:
    """Follows the ROS action goals of one robot (see the module docstring): on the loop, except what the port
    tells (`_accepted`, `_status`, `_feedback`, `_done`), which runs in the port's thread."""

    def __init__(self, ctx: RobotContext) -> None:
        self.ctx = ctx
        self._chases: dict[int, Chase] = {}  # by id of the Mission
        self._last: dict[str, _Ended] = {}  # per action: how its last goal ended

    def _port(self) -> GoalPort | None:
        port = self.ctx.port
        return port if isinstance(port, GoalPort) else None

    # -- the machine ---------------------------------------------------------------------------------------

    def start(self, m: Mission, held: threading.Event) -> None:
        """Send the goal of a mission the engine admitted (its component claimed with `held`)."""
        ctx = self.ctx
        chase = Chase(m, held)
        self._chases[id(m)] = chase
        port = self._port()
        if port is None:
            message = "this robot's port cannot send ROS action goals"
            log.warning("%s: failed: %s", m.action, message)
            self._end(chase, ProcedureStatus("failed", message=message, reason="call-failed"))
            return
        wait = max(0.0, m.started + ctx.config.mission_timeout - ctx.clock())
        chase.deadline = ctx.loop.call_later(wait, self._give_up, chase)
        if ctx.gate is not None:  # sent once the gate says so (a shared fleet: node/share.py), on the loop
            ctx.gate(partial(ctx.loop.post, self._gated, chase))
            return
        self._send(chase, port)

    def can_rejoin(self) -> bool:
        """Whether the port can follow a goal it did not send, by its id (`GoalRejoin`)."""
        return isinstance(self.ctx.port, GoalRejoin)

    def rejoin(self, m: Mission, held: threading.Event, words: str) -> None:
        """Follow on the goal `m.goal` that the last run of the node (or the robot's last owner) left in flight
        (the engine's recovery; its component claimed with `held`): its feedback from now on, numbered on from
        the ledger's, and its one terminal event. `words` say what happened to the node that sent it; they start
        the terminal event's words if the goal is lost (the server does not know it any more, or is gone)."""
        ctx = self.ctx
        port = ctx.port
        assert isinstance(port, GoalRejoin) and m.goal is not None
        status = "executing" if m.state == "running" else "accepted"
        chase = Chase(m, held, goal=m.goal, accepted=True, status=status, rejoined=words)
        self._chases[id(m)] = chase
        wait = max(0.0, m.started + ctx.config.mission_timeout - ctx.clock())
        chase.deadline = ctx.loop.call_later(wait, self._give_up, chase)
        listener, goal, timeout = _Told(self, chase), m.goal, ctx.config.call_timeout

        def follow() -> None:
            try:
                port.rejoin_goal(m.component, m.action, goal, timeout, listener)
            except PortError as exc:
                ctx.loop.post(self._done, chase, GoalEnd("lost", message=str(exc) or describe(exc), error=exc))
            except Exception:  # the last line of defence: report, never crash
                log.exception("following %s goal %s again failed internally", m.action, goal)
                ctx.loop.post(self._done, chase, GoalEnd("lost", message=INTERNAL, error=PortCallFailed(INTERNAL)))

        ctx.lane.submit(follow)

    def _gated(self, chase: Chase, go: bool) -> None:
        """The gate's answer: send the goal, or (the robot may be another process's now) end it unsent."""
        if chase.ended:  # given up or left meanwhile (the engine stops): never sent
            return
        port = self._port()
        if not go or port is None:
            message = (
                "the edge node lost its connection to the broker, and another one of the fleet may serve the robot "
                "now: not run here"
            )
            log.warning("%s goal: not sent: %s", chase.m.action, message)
            self._end(chase, ProcedureStatus("failed", message=message, reason="unreachable"))
            return
        self._send(chase, port)

    def _send(self, chase: Chase, port: GoalPort) -> None:
        """Send the goal: on the loop when the port can without waiting, else on the robot's lane."""
        ctx, m = self.ctx, chase.m
        listener = _Told(self, chase)
        args = (m.component, m.action, m.payload, ctx.config.call_timeout, listener)

        def send(start: Callable[..., str | None]) -> bool:
            """Start the goal with `start`; whether it did (False: `try_start_goal` would have waited)."""
            try:
                goal = start(*args)
            except PortError as exc:
                ctx.loop.post(self._done, chase, GoalEnd("lost", message=str(exc), error=exc))
                return True
            except Exception:  # the last line of defence: report, never crash
                log.exception("mission %s failed internally", m.action)
                ctx.loop.post(self._done, chase, GoalEnd("lost", message=INTERNAL, error=PortCallFailed(INTERNAL)))
                return True
            if goal is None:
                return False
            ctx.loop.post(self._sent, chase, goal)
            return True

        # here on the loop when the port can start it without waiting (one hand-off fewer before the goal is
        # sent), else on the robot's lane of the call pool
        if not (isinstance(port, QuickGoalStart) and send(port.try_start_goal)):
            ctx.lane.submit(lambda: void(send(port.start_goal)))

    def _sent(self, chase: Chase, goal: str) -> None:
        """start_goal returned the goal's id."""
        with chase.lock:
            chase.goal = chase.goal or goal
            ended = chase.ended
        if ended:  # given up or left meanwhile: the port forgets it now (cancelled first when given up)
            self._forget(chase, cancel=chase.cancel_when_sent)

    def _accepted(self, chase: Chase, goal: str) -> None:
        """(the port's thread) The server accepted the goal: its `queued` event."""
        with chase.lock:
            if chase.ended or chase.rejoined is not None:  # a goal followed on was accepted long ago: no event
                return
            m = chase.m
            chase.accepted, chase.goal, m.goal = True, goal, goal
            if chase.status == "unknown":
                chase.status = "accepted"
            self.ctx.outbox.feedback(m, ProcedureStatus("queued", "accepted", "goal accepted"), terminal=False)
        log.info("%s goal %s accepted", m.action, goal)  # once the event is out: a log line is a write to stderr

    def _status(self, chase: Chase, status: str) -> None:
        """(the port's thread) The goal's status changed."""
        with chase.lock:
            if not chase.ended:
                chase.status = status

    def _feedback(self, chase: Chase, message: Any) -> None:
        """(the port's thread) One feedback message: its `running` event now, or held (feedback_period)."""
        with chase.lock:
            if chase.ended:
                return
            period, now = self.ctx.config.feedback_period, self.ctx.clock()
            if period <= 0 or (chase.flush is None and now - chase.sent >= period):
                self._relay(chase, message)
                return
            chase.kept = (message,)
            if chase.flush is None:
                chase.flush = self.ctx.loop.call_later(chase.sent + period - now, self._flush, chase)

    def _flush(self, chase: Chase) -> None:
        """The held feedback message's turn (feedback_period)."""
        with chase.lock:
            chase.flush = None
            if not chase.ended and chase.kept:
                (message,), chase.kept = chase.kept, ()
                self._relay(chase, message)

    def _relay(self, chase: Chase, message: Any) -> None:
        """Publish a feedback message's `running` event (the goal's lock held)."""
        running = ProcedureStatus("running", _running_word(chase.status))
        chase.sent = self.ctx.clock()
        self.ctx.outbox.feedback(chase.m, running, terminal=False, extra={"feedback": message})

    def _done(self, chase: Chase, end: GoalEnd) -> None:
        """(the port's thread) The goal's end as the port told it: its held feedback, then the one terminal
        event."""
        with chase.lock:
            if chase.ended:
                return
            if chase.flush is not None:
                chase.flush.cancel()
                chase.flush = None
            self._flush(chase)
            self._ended(chase, end)

    def _ended(self, chase: Chase, end: GoalEnd) -> None:
        m = chase.m
        if not chase.accepted:  # it never ran: refused, or no server took it
            error = end.error or PortCallFailed(end.message)
            rejected = end.status == "rejected"
            message = (str(error) or end.message or _ENDS["rejected"]) if rejected else describe(error)
            log.warning("%s goal failed (%s): %s", m.action, error.reason, message)
            word = "rejected" if rejected else ""
            self._end(chase, ProcedureStatus("failed", word, message, reason=error.reason))
            return
        status = goal_status(end.status, True, end.message)
        if chase.rejoined is not None and end.status == "lost":  # what became of it is not known
            why = end.message or _ENDS["lost"]
            words = f"{chase.rejoined} while it followed this goal ({chase.goal}), and following it on failed: {why}"
            status = ProcedureStatus("failed", status.result, f"{words}: its outcome is unknown", reason=status.reason)
        if status.state == "failed":
            log.warning("%s goal %s: failed: %s", m.action, chase.goal, status.message)
        self._end(chase, status, output=end.result)

    def _give_up(self, chase: Chase) -> None:
        """The mission timeout passed: the goal fails, and the server is asked to cancel it."""
        with chase.lock:
            if chase.ended:
                return
            message = f"no result within the mission timeout of {self.ctx.config.mission_timeout:g} s"
            log.warning("%s goal %s: failed: %s", chase.m.action, chase.goal, message)
            chase.cancel_when_sent = True  # the server is asked to cancel it as the port forgets it
            self._end(chase, ProcedureStatus("failed", message=message, reason="timeout"))

    def _end(self, chase: Chase, status: ProcedureStatus, output: Any = None) -> None:
        """Publish the goal's terminal event and leave it, under the goal's lock: no other event of the goal
        comes after it, from whichever thread (the loop's timeout, the port's end)."""
        with chase.lock:
            if chase.ended:
                return
            if chase.goal is not None and chase.accepted:
                self._last[chase.m.action] = _Ended(chase.goal, status)
            self.ctx.outbox.finish(chase.m, status, output=output)
            chase.ended = True
        self._left(chase)

    def _leave(self, chase: Chase) -> None:
        """The machine is done with the goal without an end (left to the robot at a stop)."""
        with chase.lock:
            if chase.ended:
                return
            chase.ended = True
        self._left(chase)

    def _left(self, chase: Chase) -> None:
        """The goal is ended: its timers, the port's record of it, its component."""
        for timer in (chase.deadline, chase.flush):
            if timer is not None:
                timer.cancel()
        chase.deadline = chase.flush = None
        self._chases.pop(id(chase.m), None)
        self._forget(chase, cancel=chase.cancel_when_sent)
        self.ctx.missions.release(chase.held)
        chase.held.set()

    def _forget(self, chase: Chase, cancel: bool = False) -> None:
        """The port forgets the goal (a task on the lane; the cancel of a goal given up first, in the same task:
        two tasks of a lane may run at once)."""
        port, m, goal = self._port(), chase.m, chase.goal
        if port is None or goal is None:  # not sent yet: forgotten once start_goal returns (_sent)
            return
        timeout = self.ctx.config.call_timeout

        def answered(_canceling: bool, error: PortError | None) -> None:
            if error is not None:
                log.warning("could not cancel timed-out %s goal %s: %s", m.action, goal, describe(error))

        def forget() -> None:
            try:
                if cancel:
                    port.request_cancel(m.component, m.action, goal, timeout, answered)
                port.forget_goal(m.component, m.action, goal)
            except Exception as exc:  # noqa: BLE001 - the goal is over for us either way
                log.debug("forgetting %s goal %s: %s", m.action, goal, describe(exc))

        self.ctx.lane.submit(forget)

    def stop(self) -> None:
        """The node stops: leave every goal to the robot (no terminal event: the ledger keeps the mission)."""
        for chase in list(self._chases.values()):
            log.info("stopping: no longer following %s goal %s", chase.m.action, chase.goal)
            self._leave(chase)

    # -- query and cancel events ---------------------------------------------------------------------------

    def _followed(self, spec: EventSpec, wanted: Any) -> Callable[[Mission], bool]:
        """Whether a component's mission follows the goal a query or cancel of `spec` (for goal `wanted`) is for."""

        def match(m: Mission) -> bool:
            chase = self._chases.get(id(m))
            followed = chase is not None and chase.accepted and not chase.ended
            return followed and m.action == spec.affordance and not m.done and wanted in (None, m.goal)

        return match

    def cancel(self, spec: EventSpec, event: Mapping[str, Any]) -> None:
        """A cancel event: the server is asked to cancel the goal followed, and the answer is a state event."""
        wanted = _wanted(event)
        correlation = event.get("correlation") or event.get("id")
        m = self.ctx.missions.add_cancel(spec.component or "", correlation, self._followed(spec, wanted))
        chase = self._chases.get(id(m)) if m is not None else None
        if m is None or chase is None:
            self._answer_ended(spec, wanted, correlation)
            return
        port = self._port()
        assert port is not None and chase.goal is not None  # followed: accepted
        goal, timeout = chase.goal, self.ctx.config.call_timeout
        for taken in self.ctx.missions.take_cancels(m):
            answered = partial(self._post_cancel_answer, chase, taken)
            self.ctx.lane.submit(partial(port.request_cancel, m.component, m.action, goal, timeout, answered))

    def _post_cancel_answer(
        self, chase: Chase, correlation: str | None, canceling: bool, error: PortError | None
    ) -> None:
        """(the port's thread) The server's answer to a cancel event's request: to the loop."""
        self.ctx.loop.post(self._cancel_answered, chase, correlation, canceling, error)

    def _cancel_answered(self, chase: Chase, correlation: str | None, canceling: bool, error: PortError | None) -> None:
        m, goal = chase.m, chase.goal
        ended = self._last.get(m.action)
        if chase.ended and ended is not None and ended.goal == goal:  # it ended meanwhile: its end answers
            self.ctx.outbox.state(m.action, ended.status, correlation, None, {"goal": goal})
            return
        if error is not None:
            message = f"cancelling {m.action} goal {goal} failed: {describe(error)}"
            self._refuse(Kind.CANCEL, m.action, m.component, "call-failed", message, correlation)
            return
        word = "cancel requested" if canceling else "the server did not accept to cancel"
        status = goal_status(chase.status, False)
        status = ProcedureStatus(status.state, status.result, status.message or word, reason=status.reason)
        self.ctx.outbox.state(m.action, status, correlation, None, {"goal": goal})
        log.info("%s goal %s: %s", m.action, goal, word)

    def query(self, spec: EventSpec, event: Mapping[str, Any]) -> None:
        """A query event: the followed goal's state, else how the last one ended (no call to the robot: the
        machine knows what the port told)."""
        wanted = _wanted(event)
        correlation = event.get("correlation") or event.get("id")
        m = self.ctx.missions.find(spec.component or "", self._followed(spec, wanted))
        chase = self._chases.get(id(m)) if m is not None else None
        if chase is not None:
            self.ctx.outbox.state(
                chase.m.action, goal_status(chase.status, False), correlation, None, {"goal": chase.goal}
            )
            return
        self._answer_ended(spec, wanted, correlation)

    def _answer_ended(self, spec: EventSpec, wanted: Any, correlation: str | None) -> None:
        """A query or cancel of a goal not followed: answered with its end if this run or the ledger knows it."""
        action = spec.affordance or ""
        ended = self._last.get(action)
        if ended is None or wanted not in (None, ended.goal):
            ended = self._recorded(spec, wanted)
        if ended is not None:
            self.ctx.outbox.state(action, ended.status, correlation, None, {"goal": ended.goal})
            return
        which = f"goal {wanted}" if wanted is not None else "goal"
        message = f"{spec.kind.value}: no {action} {which} is known to this node"
        self._refuse(spec.kind, action, spec.component or "", "unsupported", message, correlation)

    def _recorded(self, spec: EventSpec, wanted: Any) -> _Ended | None:
        """How the goal `wanted` (None: the action's latest) ended, as its terminal feedback event in the ledger
        said: a goal that ended before the node's restart (or before the action's next goal) while the ledger
        keeps its row (ledger.py `ended_goal`)."""
        if wanted is not None and not isinstance(wanted, str):
            return None
        record = self.ctx.outbox.ledger.ended_goal(spec.component or "", spec.affordance or "", wanted)
        if record is None or record.goal is None or record.latest is None:
            return None
        try:
            payload = json.loads(record.latest).get("payload")
        except (ValueError, AttributeError):
            return None
        if not isinstance(payload, Mapping) or payload.get("state") not in TERMINAL_STATES:
            return None
        words = {k: payload.get(k) for k in ("result", "message", "last_event")}
        text = {k: v if isinstance(v, str) else "" for k, v in words.items()}
        reason = payload.get("reason") if isinstance(payload.get("reason"), str) else None
        status = ProcedureStatus(str(payload["state"]), text["result"], text["message"], text["last_event"], reason)
        return _Ended(record.goal, status)

    def _refuse(
        self, kind: Kind, action: str, component: str, code: str, message: str, correlation: str | None
    ) -> None:
        topic = self.ctx.topic(kind, action, component)
        self.ctx.outbox.error(code, message, topic=topic, affordance=action, correlation=correlation)


def void(_value: object) -> None:
    """Nothing (a lane task returns nothing)."""


def _wanted(event: Mapping[str, Any]) -> Any:
    payload = event.get("payload")
    return payload.get("goal") if isinstance(payload, Mapping) else None
