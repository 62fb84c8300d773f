"""The engine's side of TD actions bound to ROS actions: a goal is a mission, followed to its one end.

An invoke sends the goal (one mission per component at a time, as for procedures). Once the server accepts,
a feedback event says so (`queued`, `result: accepted`, with the goal id); then every ROS feedback message
becomes one feedback event (`running`, `result` `executing` or `canceling`, the message in `feedback`), in
order, or, with `feedback_period` > 0, at most one per period carrying the latest message; then exactly one
terminal event: `finished`
(succeeded), `cancelled` (canceled) or `failed` (aborted: reason `aborted`; refused: `rejected`; no end within
`mission_timeout`: `timeout`; the action server gone (the port says the goal is `lost`: on ROS 2 after
`action_server_timeout` of silence) or the port failing `max_query_failures` times in a row: `unreachable`), with the
server's result in `output` and its status word in `result`. A cancel event cancels the goal followed (the
mission thread asks the server, and answers with a state event; the terminal feedback follows when the
server ends the goal); a query answers with the goal's current state, or with the end of the last goal.
Every decision that fails a goal is logged.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from td2adaptor.model.events import GOAL_WORDS, EventSpec, Kind
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.missions import Mission, MissionTable
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.ros.port import GoalPort, GoalProgress, PortError, PortRejected, RobotPort
from td2adaptor.runtime.ros.procedures import ProcedureStatus
from td2adaptor.runtime.ros.words import describe

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


def goal_status(progress: GoalProgress) -> ProcedureStatus:
    """A goal's progress as a procedure state; the status word is kept as `result`, the server's words (or
    ours, when it said nothing) as `message`."""
    word = progress.status
    state = _STATES.get(word, "running")
    if progress.done and state not in ("finished", "cancelled", "failed"):
        return ProcedureStatus("failed", word, f"the goal ended with status {word}", reason="robot-error")
    reason = _REASONS.get(word, "robot-error") if state == "failed" else None
    message = progress.message or (_ENDS.get(word, "") if progress.done else "")
    return ProcedureStatus(state, word if word in GOAL_WORDS else "unknown", message, reason=reason)


def _running_word(word: str) -> str:
    """The status word a `running` feedback event carries: the goal's own while it runs (`canceling`), else
    `executing`. A server sends feedback only while it executes the goal, but the goal's status may already say
    how it ended (the result came first, the feedback trails it, or is held back by `feedback_period`): that word
    belongs to the terminal event alone."""
    return word if _STATES.get(word) == "running" else "executing"


@dataclass(frozen=True)
class _Ended:
    goal: str
    status: ProcedureStatus


class GoalRunner:
    """Follows the ROS action goals of one robot (see the module docstring): its missions in the engine's
    `missions` table, its events through the engine's `outbox`; queries and cancels of goals nobody follows
    are answered through `submit` (the robot's lane of the call pool); `stopping` set, the goals are left to
    the robot."""

    def __init__(
        self,
        port: RobotPort,
        config: RuntimeConfig,
        missions: MissionTable,
        outbox: Outbox,
        submit: Callable[..., None],
        stopping: threading.Event,
        clock: Callable[[], float],
    ) -> None:
        self.port = port
        self.config = config
        self.missions = missions
        self.outbox = outbox
        self.submit = submit
        self.stopping = stopping
        self.clock = clock
        self._lock = threading.Lock()
        self._last: dict[str, _Ended] = {}  # per action: how its last goal ended

    def _port(self) -> GoalPort | None:
        port = self.port
        return port if isinstance(port, GoalPort) else None

    # -- the mission thread --------------------------------------------------------------------------------

    def follow(self, m: Mission) -> None:
        """Send the goal and report it until its end (run in the mission's own thread)."""
        out, cfg = self.outbox, self.config
        port = self._port()
        if port is None:
            message = "this robot's port cannot send ROS action goals"
            log.warning("%s: failed: %s", m.action, message)
            out.finish(m, ProcedureStatus("failed", message=message, reason="call-failed"))
            return
        try:
            goal = port.send_goal(m.component, m.action, m.payload, cfg.call_timeout)
        except PortError as exc:
            word = "rejected" if isinstance(exc, PortRejected) else ""
            message = (str(exc) or "the action server rejected the goal") if word else describe(exc)
            log.warning("%s goal failed (%s): %s", m.action, exc.reason, message)
            out.finish(m, ProcedureStatus("failed", word, message, reason=exc.reason))
            return
        m.goal = goal
        log.info("%s goal %s accepted", m.action, goal)
        out.feedback(m, ProcedureStatus("queued", "accepted", "goal accepted"), terminal=False)
        try:
            self._watch(port, m, goal)
        finally:
            try:
                port.forget_goal(m.component, m.action, goal)
            except Exception as exc:  # noqa: BLE001 - the goal is over for us either way
                log.debug("forgetting %s goal %s: %s", m.action, goal, describe(exc))

    def _watch(self, port: GoalPort, m: Mission, goal: str) -> None:
        out, cfg = self.outbox, self.config
        deadline = m.started + cfg.mission_timeout
        since, failures, sent = 0, 0, -1e18
        held: Any = None
        while True:
            if self.stopping.is_set():
                log.info("stopping: no longer following %s goal %s", m.action, goal)
                return
            self._carry_out_cancels(port, m, goal)
            remaining = deadline - self.clock()
            if remaining <= 0:
                self._give_up(port, m, goal)
                return
            try:
                progress = port.goal_progress(m.component, m.action, goal, since, min(cfg.poll_period, remaining))
            except Exception as exc:
                failures += 1
                log.warning("following %s goal %s failed (%d): %s", m.action, goal, failures, describe(exc))
                if failures >= cfg.max_query_failures:
                    message = f"the robot did not answer {failures} times: {describe(exc)}"
                    log.warning("%s goal %s: failed: %s", m.action, goal, message)
                    out.finish(m, ProcedureStatus("failed", message=message, reason="unreachable"))
                    return
                continue
            failures = 0
            since = progress.received
            running = ProcedureStatus("running", _running_word(progress.status))
            for message in progress.feedback:
                if cfg.feedback_period <= 0:
                    out.feedback(m, running, terminal=False, extra={"feedback": message})
                else:
                    held = message
            if held is not None and (progress.done or self.clock() - sent >= cfg.feedback_period):
                out.feedback(m, running, terminal=False, extra={"feedback": held})
                held, sent = None, self.clock()
            if progress.done:
                status = goal_status(progress)
                if status.state == "failed":
                    log.warning("%s goal %s: failed: %s", m.action, goal, status.message)
                self._remember(m.action, goal, status)
                out.finish(m, status, output=progress.result)
                return

    def _give_up(self, port: GoalPort, m: Mission, goal: str) -> None:
        out, cfg = self.outbox, self.config
        message = f"no result within the mission timeout of {cfg.mission_timeout:g} s"
        log.warning("%s goal %s: failed: %s", m.action, goal, message)
        status = ProcedureStatus("failed", message=message, reason="timeout")
        self._remember(m.action, goal, status)
        out.finish(m, status)
        try:
            port.cancel_goal(m.component, m.action, goal, cfg.call_timeout)
        except Exception as exc:  # noqa: BLE001 - the server may be gone: that is why we gave up
            log.warning("could not cancel timed-out %s goal %s: %s", m.action, goal, describe(exc))

    def _carry_out_cancels(self, port: GoalPort, m: Mission, goal: str) -> None:
        """Cancel events for the goal followed: ask the server, answer each with a state event."""
        for correlation in self.missions.take_cancels(m):
            try:
                accepted = port.cancel_goal(m.component, m.action, goal, self.config.call_timeout)
                progress = port.goal_progress(m.component, m.action, goal, None, 0.0)
            except Exception as exc:
                message = f"cancelling {m.action} goal {goal} failed: {describe(exc)}"
                self._refuse(Kind.CANCEL, m.action, m.component, "call-failed", message, correlation)
                continue
            status = goal_status(progress)
            word = "cancel requested" if accepted else "the server did not accept to cancel"
            log.info("%s goal %s: %s", m.action, goal, word)
            status = ProcedureStatus(status.state, status.result, status.message or word, reason=status.reason)
            self.outbox.state(m.action, status, correlation, None, {"goal": goal})

    def _remember(self, action: str, goal: str, status: ProcedureStatus) -> None:
        with self._lock:
            self._last[action] = _Ended(goal, status)

    # -- query and cancel events ---------------------------------------------------------------------------

    @staticmethod
    def _followed(spec: EventSpec, wanted: Any) -> Callable[[Mission], bool]:
        """Whether a component's mission follows the goal a query or cancel of `spec` (for goal `wanted`) is for."""
        return lambda m: m.action == spec.affordance and not m.done and m.goal is not None and wanted in (None, m.goal)

    def cancel(self, spec: EventSpec, event: Mapping[str, Any]) -> None:
        """A cancel event (the engine's loop): hand it to the mission that follows the goal."""
        wanted = _wanted(event)
        correlation = event.get("correlation") or event.get("id")
        if self.missions.add_cancel(spec.component or "", correlation, self._followed(spec, wanted)) is not None:
            return
        self.submit(self._answer_ended, spec, wanted, correlation)

    def query(self, spec: EventSpec, event: Mapping[str, Any]) -> None:
        """A query event (pool thread): the followed goal's state, else how the last one ended."""
        wanted = _wanted(event)
        correlation = event.get("correlation") or event.get("id")
        port = self._port()
        m = self.missions.find(spec.component or "", self._followed(spec, wanted))
        if m is not None and m.goal is not None and port is not None:
            try:
                progress = port.goal_progress(m.component, m.action, m.goal, None, 0.0)
            except Exception as exc:
                message = f"querying {m.action} goal {m.goal} failed: {describe(exc)}"
                self._refuse(Kind.QUERY, m.action, m.component, "call-failed", message, correlation)
                return
            self.outbox.state(m.action, goal_status(progress), correlation, None, {"goal": m.goal})
            return
        self._answer_ended(spec, wanted, correlation)

    def _answer_ended(self, spec: EventSpec, wanted: Any, correlation: str | None) -> None:
        action = spec.affordance or ""
        with self._lock:
            ended = self._last.get(action)
        if ended is not None and wanted in (None, ended.goal):
            self.outbox.state(action, ended.status, correlation, None, {"goal": ended.goal})
            return
        which = f"goal {wanted}" if wanted is not None else "goal"
        message = f"{spec.kind.value}: no {action} {which} is known to this node"
        self._refuse(spec.kind, action, spec.component or "", "unsupported", message, correlation)

    def _refuse(
        self, kind: Kind, action: str, component: str, code: str, message: str, correlation: str | None
    ) -> None:
        catalog, cfg = self.outbox.catalog, self.config
        spec = next(
            (s for s in catalog.specs if s.kind is kind and s.affordance == action and s.component == component),
            None,
        )
        topic = spec.topic(cfg.robot, cfg.topic_root) if spec is not None else ""
        self.outbox.error(code, message, topic=topic, affordance=action, correlation=correlation)


def _wanted(event: Mapping[str, Any]) -> Any:
    payload = event.get("payload")
    return payload.get("goal") if isinstance(payload, Mapping) else None
