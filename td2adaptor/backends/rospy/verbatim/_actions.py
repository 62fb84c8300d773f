"""Run-time support of ROS 1 actions (actionlib): goals sent over `<name>/goal`, followed on `<name>/status`,
`<name>/feedback` and `<name>/result`, cancelled on `<name>/cancel`. Copied only into packages with actions,
which then need actionlib (Debian's python3-actionlib).

Mirrors the ROS 2 (rclpy) adaptor's actions: `ActionGoalClient.start` and `send` return a `GoalHandle` with the
same members, built on the same goal record (goals.py), and no method waits longer than its timeout, whatever
the robot does. ROS 1 acknowledges a goal only through the status topic, so a goal counts as accepted once the
server reports it (pending included) or sends its feedback, and `send` waits for the server to take the goal
up (or reject it). rospy runs callbacks in its own threads, so any thread may block here; one thread of the
adaptor ("adaptor-goals", one per process) keeps the time of every goal: liveness, deadlines, feedback grace.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
import uuid
import weakref
import xmlrpc.client
from collections.abc import Callable
from typing import Any, Generic, TypeVar, cast

import actionlib
import rospy

from ._runtime import MasterState, TimedTransport, require_node
from .common import check_timeout
from .errors import (
    AdaptorError,
    CallFailed,
    CallTimeout,
    GoalAborted,
    GoalCanceled,
    GoalRejected,
    InvalidMessage,
    ServiceUnavailable,
)
from .goals import CancelOutcome, CancelRequest, GoalOutcome, GoalRecord

GoalT = TypeVar("GoalT")
ResultT = TypeVar("ResultT")
FeedbackT = TypeVar("FeedbackT")

#: how often a wait for an action server re-checks its connections
POLL_PERIOD = 0.02
#: how long a wait for an action server gives the server's XML-RPC API to answer getBusInfo
BUS_INFO_TIMEOUT = 2.0
#: goals of one action client sent and not reported by the server yet, at most (later ones wait their turn in
#: their handles): actionlib's goal publisher queues 10 messages, and rospy drops the oldest beyond that
GOAL_REQUESTS = 4
#: how often the goals' thread checks that the action server of each goal in flight is still connected
LIVENESS_PERIOD = 0.1
#: seconds a goal's end waits for feedback that trails its result (`feedback_grace`, see GoalRecord): rospy
#: reads the feedback and the result connections in two threads, so a message the server published right
#: before the result often arrives after it
FEEDBACK_GRACE = 0.1

#: actionlib_msgs/GoalStatus codes → the status a GoalHandle reports (the ROS 2 adaptor's words where they
#: exist; ROS 1 adds "pending": received, not started, may still be rejected; "rejected" and "lost")
GOAL_STATUS = {
    0: "pending",
    1: "executing",
    2: "canceled",  # PREEMPTED: canceled while executing
    3: "succeeded",
    4: "aborted",
    5: "rejected",
    6: "canceling",  # PREEMPTING
    7: "canceling",  # RECALLING: cancel asked before it started
    8: "canceled",  # RECALLED
    9: "lost",
}
_PENDING, _ACTIVE, _PREEMPTED, _SUCCEEDED, _ABORTED, _REJECTED, _PREEMPTING, _RECALLING, _RECALLED, _LOST = range(10)
#: actionlib's CommState values the adaptor reads: a cancel of ours on its way (no news from the server), DONE
_WAITING_FOR_CANCEL_ACK, _DONE = 4, 7
#: the statuses of a goal that runs
_RUNNING = (_PENDING, _ACTIVE, _PREEMPTING, _RECALLING)
#: the statuses that answer a cancel request with "canceling"
_CANCELING = (_PREEMPTING, _RECALLING, _PREEMPTED, _RECALLED)
#: actionlib's CommState values a followed goal (`ActionGoalClient.rejoin`) starts in: PENDING (a goal the server
#: no longer lists then ends lost), and WAITING_FOR_RESULT (its status says it ended: the result is on its way)
_COMM_PENDING, _WAITING_FOR_RESULT = 1, 3
#: seconds a followed goal that the status list says has ended waits for its result: the server published it
#: before this client followed the goal, and actionlib never sends it again; its end is then the status's
RESULT_WAIT = 1.0
#: the "goal" of a handle that follows a goal the server already has (`ActionGoalClient.rejoin`): nothing to send
_REJOIN = object()


class _Clock:
    """The adaptor's one thread for the time of ROS 1 goals, started with the first goal: every
    LIVENESS_PERIOD it looks after the goals in flight (their server's connections, their deadlines, a server
    they wait for), and it runs what the goals schedule (`later`: the end of a feedback grace, an answer that
    must not come inside the caller's call). It sleeps while no goal is in flight; no goal has a thread."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._due: list[tuple[float, int, Callable[[], object]]] = []  # a heap
        self._order = itertools.count()
        self._goals: list[GoalHandle[Any, Any]] = []
        self._next_tick = 0.0
        self._thread: threading.Thread | None = None

    def watch(self, goal: GoalHandle[Any, Any]) -> None:
        """Look after `goal` from now on, until its `tick` says it is over."""
        with self._cond:
            if not self._goals:
                self._next_tick = time.monotonic() + LIVENESS_PERIOD
            self._goals.append(goal)
            self._start()
            self._cond.notify()  # it may sleep without a deadline (no goal was in flight)

    def later(self, delay: float, action: Callable[[], object]) -> None:
        """Run `action` in this thread after `delay` seconds."""
        with self._cond:
            heapq.heappush(self._due, (time.monotonic() + delay, next(self._order), action))
            self._start()
            self._cond.notify()

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="adaptor-goals", daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while True:
            with self._cond:
                now, due, goals = self._wait()
            for action in due:
                try:
                    action()
                except Exception as exc:  # noqa: BLE001 - report it and keep the time of the others
                    rospy.logerr(f"a goal's scheduled work raised {type(exc).__name__}: {exc}")
            over: set[int] = set()
            for goal in goals:
                try:
                    if not goal.tick(now):
                        over.add(id(goal))
                except Exception as exc:  # noqa: BLE001 - one goal must not stop the others' care
                    rospy.logerr(f"{goal.action}: looking after the goal raised {type(exc).__name__}: {exc}")
            if over:
                with self._cond:
                    self._goals = [goal for goal in self._goals if id(goal) not in over]

    def _wait(self) -> tuple[float, list[Callable[[], object]], list[GoalHandle[Any, Any]]]:
        """Wait until something is due (lock held): the time, what is due, the goals to look after."""
        while True:
            now = time.monotonic()
            due: list[Callable[[], object]] = []
            while self._due and self._due[0][0] <= now:
                due.append(heapq.heappop(self._due)[2])
            tick = bool(self._goals) and now >= self._next_tick
            if due or tick:
                if tick:
                    self._next_tick = now + LIVENESS_PERIOD
                return now, due, list(self._goals) if tick else []
            waits = [self._due[0][0] - now] if self._due else []
            if self._goals:
                waits.append(self._next_tick - now)
            self._cond.wait(min(waits) if waits else None)


_CLOCK = _Clock()


class GoalHandle(GoalRecord[ResultT, FeedbackT]):
    """One goal sent to a ROS 1 action server (`send_X` returns it taken up, `start_X` at once).

    `goal_id` is the goal's id (a string, made before the goal is sent), `status` its latest status
    ("unknown" before the first report, "pending", "executing", "canceling", then "succeeded", "canceled",
    "aborted", "rejected" or "lost"), `reason` the server's words with it (often empty), `done` whether the
    server ended it (actionlib's DONE), `outcome` how it ended (a GoalOutcome), once it did.

    What happens to the goal is told to the callbacks given to `start_X` (see GoalRecord: on_accepted,
    on_status, on_feedback, then exactly one on_done), and to `on_feedback(callback)` callbacks added later.
    They run in rospy's receive threads or in the adaptor's goals thread, never two at once for one goal: they
    must return quickly. Feedback and result travel on two connections, so a message the server published
    right before the result may arrive just after it: it still reaches the callbacks (within the goal's
    `feedback_grace`) and the buffer (actionlib's own client would drop it). `feedback(timeout=...)` iterates
    over the feedback in the caller's thread until the goal's end is told, `result(timeout=...)` waits for the
    end, `cancel(timeout=...)` asks the server to cancel the goal and waits until it takes the request up,
    `request_cancel(on_done)` asks without waiting. No method waits longer than its timeout, and a goal ends
    lost with ServiceUnavailable when its action server goes away (ROS 1 would not tell otherwise: a dead
    server just stops publishing).
    """

    def __init__(
        self,
        action: str,
        timeout: float,
        client: ActionGoalClient[Any, ResultT, FeedbackT],
        goal_id: str,
        on_accepted: Callable[[], None] | None = None,
        on_status: Callable[[str], None] | None = None,
        on_feedback: Callable[[FeedbackT], None] | None = None,
        on_done: Callable[[GoalOutcome[ResultT]], None] | None = None,
        feedback_grace: float = FEEDBACK_GRACE,
    ) -> None:
        super().__init__(action, timeout, on_accepted, on_status, on_feedback, on_done, feedback_grace)
        self.goal_id = goal_id
        self._client = client
        self._raw: actionlib.ClientGoalHandle | None = None  # once sent
        self._goal: Any = None  # the goal while it waits for a server
        self._wait_timeout = 0.0
        self._server_deadline = 0.0
        self._accept_deadline = 0.0
        self._queued = False  # waits its turn to be sent (GOAL_REQUESTS)
        self._admitted = False  # sent and not reported yet: holds one of the client's GOAL_REQUESTS
        self._reason = ""  # the server's words with the latest status
        self._missing = 0  # liveness checks in a row that found no server connected
        self.rejoined = False  # followed by its id (`ActionGoalClient.rejoin`), not sent by this handle

    @property
    def reason(self) -> str:
        """The server's words with the latest status (actionlib's status text; often empty)."""
        with self._cond:
            return self._reason

    # hooks of GoalRecord

    def _log(self, text: str) -> None:
        rospy.logerr(text)

    def _later(self, delay: float, action: Callable[[], object]) -> None:
        _CLOCK.later(delay, action)

    def _closing(self) -> None:
        self._client.forget(self)

    # the goal's way (ActionGoalClient, rospy's threads, the goals thread; not for callers)

    def begin(self, goal: Any, wait_timeout: float) -> None:
        """Hold `goal` until it is sent (at most `wait_timeout` seconds from now)."""
        with self._cond:
            self._goal, self._wait_timeout = goal, wait_timeout
            self._server_deadline = time.monotonic() + wait_timeout
        _CLOCK.watch(self)

    def queue(self) -> None:
        """The goal waits its turn to be sent (ActionGoalClient)."""
        with self._cond:
            self._queued = True

    def take_goal(self) -> Any:
        """The goal to send now, which then holds one of the client's turns (None: sent already, or the goal is
        over; the turn is the caller's to give back)."""
        with self._cond:
            goal, self._goal = self._goal, None
            self._queued = False
            self._admitted = goal is not None and self._outcome is None
            self._accept_deadline = time.monotonic() + self.timeout
            return goal if self._admitted else None

    def _give_back(self) -> None:
        """The server reported the goal (or it is over): its turn goes to the next goal in line."""
        with self._cond:
            if not self._admitted or not (self._accepted or self._outcome is not None):
                return
            self._admitted = False
        self._client.turn_over()

    def attach(self, raw: actionlib.ClientGoalHandle) -> None:
        """The goal was sent as `raw` (by ActionGoalClient)."""
        with self._cond:
            self._raw = raw
            unsent = [request for request in self._cancels if not request.sent]
        for request in unsent:
            self._send_cancel(request)

    def transition(self, raw: actionlib.ClientGoalHandle) -> None:
        """A change of the goal's state (actionlib's transition callback, in rospy's threads)."""
        comm = int(raw.get_comm_state())
        if comm == _WAITING_FOR_CANCEL_ACK:
            return  # our own cancel request on its way: nothing new from the server
        code = int(raw.get_goal_status())
        text = str(raw.get_goal_status_text())
        with self._cond:
            self._reason = text
            sent = [request for request in self._cancels if request.sent]
        # a rejection reported before its result (status and result travel on two connections, and on a loaded
        # machine the status often comes first) was never taken up: the result, with the server's words, ends it
        if comm != _DONE and code != _REJECTED:
            # a terminal code here: the result is on its way (WAITING_FOR_RESULT)
            self._accept(GOAL_STATUS[code] if code in _RUNNING else "executing")
            if code in _RUNNING:
                self._set_status(GOAL_STATUS[code])
        if code in _CANCELING or comm == _DONE:
            for request in sent:
                self._answer(request, CancelOutcome(code in _CANCELING))
        if comm == _DONE:
            self._finish(code, text, raw.get_result())
        elif comm == _WAITING_FOR_RESULT and self.rejoined:  # its result may have been sent before we followed it
            _CLOCK.later(RESULT_WAIT, lambda: self._finish(code, text, None))
        self._give_back()

    def _finish(self, code: int, text: str, result: Any) -> None:
        if code == _REJECTED:
            self._end(GoalOutcome("rejected", result, GoalRejected(self.action, text), text), by_server=True)
            return
        if not self.rejoined or code in (_SUCCEEDED, _ABORTED, _PREEMPTED, _RECALLED):
            self._accept("executing")  # ended without a report of it running first (a goal followed by its id
            # that the server does not know was never accepted: no on_accepted, no status, only its end)
        if code == _SUCCEEDED:
            outcome: GoalOutcome[Any] = GoalOutcome("succeeded", result, None, text)
        elif code == _ABORTED:
            outcome = GoalOutcome("aborted", result, GoalAborted(self.action, result, text), text)
        elif code in (_PREEMPTED, _RECALLED):
            outcome = GoalOutcome("canceled", result, GoalCanceled(self.action, result, text), text)
        elif self.rejoined:  # followed by its id: the server forgot it (it ended a while ago), or never had it
            failed = CallFailed(self.action, f"the action server does not know goal {self.goal_id}")
            outcome = GoalOutcome("lost", None, failed, text or failed.message)  # the words, as on ROS 2
        else:  # no result, as on ROS 2: whatever result message came with it is not the goal's
            failed = CallFailed(self.action, f"the goal was lost (status {code}: the server forgot it)")
            outcome = GoalOutcome("lost", None, failed, text)
        self._end(outcome, by_server=True)

    def deliver(self, feedback: FeedbackT) -> None:
        """One feedback message of this goal (from ActionGoalClient's feedback subscription): the server
        executes the goal, so it took it up."""
        self._accept("executing")
        self._feedback_in(feedback)
        if self._admitted:
            self._give_back()

    def tick(self, now: float) -> bool:
        """Look after the goal (the goals thread, every LIVENESS_PERIOD); whether it still needs to be."""
        self._expire(now)
        with self._cond:
            if self._outcome is not None:
                return bool(self._cancels)
            waiting, queued, accepted = self._goal is not None, self._queued, self._accepted
        if waiting and not queued:
            if self._client.server_ready():
                self._client.send_now(self)
            elif now >= self._server_deadline:
                self._lose(
                    ServiceUnavailable(self.action, f"no action server within {self._wait_timeout:g} s", kind="action")
                )
        elif not waiting and not accepted and now >= self._accept_deadline:
            self.give_up()
        else:  # running, or waiting its turn: its server must stay
            self._missing = 0 if self._client.server_connected() else self._missing + 1
            if self._missing >= 2:  # twice in a row: once could be a connection being remade
                self._lose(
                    ServiceUnavailable(self.action, "the action server went away during the goal", kind="action")
                )
        return True

    def _lose(self, error: AdaptorError, unless_accepted: bool = False) -> bool:
        reason = str(getattr(error, "reason", "") or getattr(error, "message", "") or error)
        lost = self._end(GoalOutcome("lost", None, error, reason), by_server=False, unless_accepted=unless_accepted)
        if lost:
            with self._cond:
                queued, self._queued = self._queued, False
            if queued:
                self._client.withdraw(self)
            self._give_back()
        return lost

    def fail(self, error: AdaptorError) -> None:
        """The goal could not be sent (ActionGoalClient): it is lost, as told in the goals thread (never inside
        the caller's start_X)."""
        _CLOCK.later(0.0, lambda: self._lose(error))

    def give_up(self) -> None:
        """The server did not report the goal in time: it is lost, and cancelled (the server may still take it
        up: nobody would follow it)."""
        if self._client.server_ready(ask=False):
            error: AdaptorError = CallTimeout(self.action, self.timeout)
        else:
            error = ServiceUnavailable(self.action, f"the server went away within {self.timeout:g} s", kind="action")
        if self._lose(error, unless_accepted=True):
            with self._cond:
                raw, self._goal = self._raw, None
            if raw is not None and not self.rejoined:  # a goal followed by its id is not ours to cancel
                _CLOCK.later(0.0, raw.cancel)

    def _send_cancel(self, request: CancelRequest) -> None:
        with self._cond:
            raw = self._raw
            if raw is None or request.sent:
                return  # sent with the goal
            request.sent = True
        # in the goals thread: actionlib calls the transition callback in the caller's thread, under its lock
        _CLOCK.later(0.0, raw.cancel)

    # waiting, for callers

    def wait_taken_up(self, timeout: float) -> None:
        """Wait at most `timeout` seconds for the server to start the goal, end it or reject it; raises why it
        did not take the goal (GoalRejected; without a report in time CallTimeout or ServiceUnavailable, and the
        goal is given up). A goal the server reports but leaves pending is left as it is."""
        with self._cond:
            self._cond.wait_for(
                lambda: self._outcome is not None or self._status not in ("unknown", "pending"), timeout
            )
            reported = self._accepted or self._outcome is not None
        if not reported:
            self.give_up()
        with self._cond:
            outcome = self._outcome
        if outcome is not None and (outcome.status == "rejected" or not self._accepted):
            outcome.get()


def _publishers(subscription: rospy.Subscriber) -> set[str]:
    """The XML-RPC URIs of the nodes `subscription` is connected to (rospy keeps them as endpoint ids)."""
    return {str(connection.endpoint_id) for connection in list(subscription.impl.connections)}


def _topics_sent_to(uri: str, caller_id: str) -> set[str] | None:
    """The topics the node at `uri` publishes to `caller_id` by its getBusInfo (empty when it cannot be
    reached yet), or None when it has no getBusInfo (then nothing more than the connection counts is known)."""
    try:
        proxy = xmlrpc.client.ServerProxy(uri, transport=TimedTransport(BUS_INFO_TIMEOUT))
        reply: Any = proxy.getBusInfo(caller_id)
    except xmlrpc.client.Fault:
        return None
    except (OSError, xmlrpc.client.Error, ValueError):
        return set()  # not reachable (yet): the caller polls again
    try:
        code, _, rows = cast(tuple[int, str, list[list[Any]]], tuple(reply))
        return {str(row[4]) for row in rows if code == 1 and row[1] == caller_id and row[2] == "o"}
    except (TypeError, ValueError, IndexError):  # not getBusInfo's reply shape
        return set()


class ActionGoalClient(Generic[GoalT, ResultT, FeedbackT]):
    """One ROS 1 action client (`actionlib.ActionClient`) that never waits forever.

    `start` sends a goal without waiting and returns its GoalHandle at once: what happens is told to its
    callbacks (see GoalHandle). `send` waits at most `wait_timeout` for an action server (ServiceUnavailable),
    then at most `timeout` for the server to take the goal up: GoalRejected when it rejects it, CallTimeout when
    it never reports the goal (the goal is then cancelled). A goal the server reports but leaves pending is
    returned as it is. Both follow the goal the same way.
    """

    def __init__(
        self,
        name: str,
        action_class: type[Any],
        goal_class: type[GoalT],
        result_class: type[ResultT],
        feedback_class: type[FeedbackT],
    ) -> None:
        self.name = name
        self._action_class = action_class  # genaction's NameAction: actionlib takes the other classes from it
        self._goal_class = goal_class
        self.result_class = result_class
        self.feedback_class = feedback_class
        self._lock = threading.Lock()
        self._client: actionlib.ActionClient | None = None
        # actionlib's client drops a feedback message that arrives after the goal's result (update_feedback
        # ignores it once DONE), which happens whenever the server publishes the two back to back: this
        # client subscribes to the feedback topic itself and hands each message to its goal's handle.
        self._feedback_sub: rospy.Subscriber | None = None
        self._goals: dict[str, GoalHandle[ResultT, FeedbackT]] = {}  # the goals followed, by id
        self._goals_lock = threading.Lock()  # held while a goal is sent (its id is handed to actionlib)
        self._next_id = ""  # the id actionlib gives the goal being sent
        self._window = threading.Lock()
        self._unreported = 0  # goals sent and not reported by the server yet (GOAL_REQUESTS)
        self._line: list[GoalHandle[ResultT, FeedbackT]] = []  # goals waiting for their turn, oldest first
        self._servers_seen: set[str] = set()  # XML-RPC URIs of servers known to publish to this node

    def register(self) -> None:
        """Create the action client (its goal/cancel publishers and status/feedback/result subscribers)."""
        if self._client is None:
            require_node()
            with self._lock:
                if self._client is None:
                    client = actionlib.ActionClient(self.name, self._action_class)
                    # the goal's id is made before it is sent (a goal may wait for its server): actionlib
                    # takes it from its manager's id maker, which keeps making its own otherwise
                    make_id = vars(type(client.manager))["_generate_id"]
                    vars(client.manager)["_generate_id"] = lambda: self._goal_id(make_id(client.manager))
                    topic = client.feedback_sub.resolved_name
                    self._feedback_sub = rospy.Subscriber(topic, client.ActionFeedback, self._on_feedback)
                    self._client = client

    def ready(self, state: MasterState) -> bool:
        """Whether an action server is there in `state` (what the ROS master knew a moment ago): someone
        publishes the action's `status` topic, as every actionlib server does."""
        return rospy.resolve_name(self.name) + "/status" in state.publishers

    def _goal_id(self, made: Any) -> Any:
        """actionlib's new GoalID (its stamp: now), with the id of the goal being sent."""
        if self._next_id:
            made.id = self._next_id
        return made

    def _on_feedback(self, message: Any) -> None:
        """A message on the feedback topic (rospy's receive thread): to its goal's handle, if it is ours."""
        handle = self._goals.get(str(message.status.goal_id.id))
        if handle is not None:
            handle.deliver(cast(FeedbackT, message.feedback))

    def forget(self, handle: GoalHandle[ResultT, FeedbackT]) -> None:
        """`handle`'s story is told: its feedback goes nowhere from now on."""
        with self._goals_lock:
            if self._goals.get(handle.goal_id) is handle:
                del self._goals[handle.goal_id]

    def close(self) -> None:
        """Unregister the client's publishers and subscribers; register() (or send) sets them up again."""
        with self._lock:
            client, self._client = self._client, None
            subscription, self._feedback_sub = self._feedback_sub, None
        if subscription is not None:
            subscription.unregister()
        if client is not None:
            client.stop()

    def server_ready(self, ask: bool = True) -> bool:
        """Whether an action server is connected on all five topics and has reported its status (`ask`: the
        first time, ask a new server process whether it sends to us, else take it as not ready yet)."""
        client = self._client
        if client is None or client.last_status_msg is None:
            return False
        parts = (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub)
        return all(part.get_num_connections() > 0 for part in parts) and self._server_sends_to_us(client, ask)

    def _server_sends_to_us(self, client: actionlib.ActionClient, ask: bool) -> bool:
        """Whether the servers' feedback and result publishers have taken this node's subscriptions up.

        rospy (and roscpp) count a subscription as connected once the publisher has answered its handshake,
        but the publisher adds it to its own list only after that: a message published in between (a goal's
        first feedback, a quick result) never reaches us. The server's getBusInfo tells; asked once per
        server process (its XML-RPC URI, new on every start), and only when `ask`."""
        servers = _publishers(client.feedback_sub) & _publishers(client.result_sub)
        me = rospy.get_caller_id()
        topics = {client.feedback_sub.resolved_name, client.result_sub.resolved_name}
        for uri in servers - self._servers_seen:
            if not ask:
                return False
            sending = _topics_sent_to(uri, me)
            if sending is not None and not topics <= sending:
                return False
            self._servers_seen.add(uri)
        return bool(servers)

    def server_connected(self) -> bool:
        """Whether an action server is still connected (its status and result publishers)."""
        client = self._client
        return client is not None and (
            client.status_sub.get_num_connections() > 0 or client.result_sub.get_num_connections() > 0
        )

    def _check_goal(self, goal: GoalT) -> None:
        if not isinstance(goal, self._goal_class):
            expected = getattr(self._goal_class, "_type", self._goal_class.__name__)
            raise InvalidMessage(f"{self.name}: expected {expected}, not {type(goal).__name__}")

    def start(
        self,
        goal: GoalT,
        timeout: float,
        wait_timeout: float,
        *,
        on_accepted: Callable[[], None] | None = None,
        on_status: Callable[[str], None] | None = None,
        on_feedback: Callable[[FeedbackT], None] | None = None,
        on_done: Callable[[GoalOutcome[ResultT]], None] | None = None,
        feedback_grace: float | None = None,
    ) -> GoalHandle[ResultT, FeedbackT]:
        """Send `goal` without waiting (see the class docstring): to the server now, or once one is there
        within `wait_timeout` (else the goal ends lost with ServiceUnavailable). The server must report it
        within `timeout` (else it ends lost with CallTimeout, and is cancelled). Raises only InvalidMessage (a
        goal of another type), ValueError (a bad timeout) and NotInitialized; everything else comes through the
        callbacks. The first goal registers the client with the master (call register() earlier to have that
        done beforehand)."""
        timeout, wait_timeout = check_timeout(timeout, "timeout"), check_timeout(wait_timeout, "wait_timeout")
        self._check_goal(goal)
        self.register()
        grace = FEEDBACK_GRACE if feedback_grace is None else feedback_grace
        goal_id = f"{rospy.get_caller_id()}-{uuid.uuid4().hex}"
        handle = GoalHandle[ResultT, FeedbackT](
            self.name, timeout, self, goal_id, on_accepted, on_status, on_feedback, on_done, grace
        )
        with self._goals_lock:
            self._goals[goal_id] = handle
        handle.begin(goal, wait_timeout)
        if self.server_ready(ask=False):
            self.send_now(handle)
        return handle

    def rejoin(
        self,
        goal_id: str,
        timeout: float,
        wait_timeout: float,
        *,
        on_accepted: Callable[[], None] | None = None,
        on_status: Callable[[str], None] | None = None,
        on_feedback: Callable[[FeedbackT], None] | None = None,
        on_done: Callable[[GoalOutcome[ResultT]], None] | None = None,
        feedback_grace: float | None = None,
    ) -> GoalHandle[ResultT, FeedbackT]:
        """Follow the goal `goal_id` that the server took from another client (this process before a restart,
        another process), without waiting: its GoalHandle at once, then the callbacks as for `start`, from
        on_accepted (once the server reports the goal) on. Feedback comes from now on; the end is the result the
        server publishes, or, for a goal that ended before it was followed (the server lists its status a few
        seconds more, not its result), the status's end without a result after RESULT_WAIT; lost (CallFailed)
        when the server does not list the goal, or no server is there within `wait_timeout`. Raises only
        ValueError (an empty id, a bad timeout) and NotInitialized."""
        timeout, wait_timeout = check_timeout(timeout, "timeout"), check_timeout(wait_timeout, "wait_timeout")
        text = str(goal_id).strip()
        if not text:
            raise ValueError(f"{self.name}: a goal id must not be empty")
        self.register()
        grace = FEEDBACK_GRACE if feedback_grace is None else feedback_grace
        handle = GoalHandle[ResultT, FeedbackT](
            self.name, timeout, self, text, on_accepted, on_status, on_feedback, on_done, grace
        )
        handle.rejoined = True
        with self._goals_lock:
            self._goals[text] = handle
        handle.begin(_REJOIN, wait_timeout)
        if self.server_ready(ask=False):
            self.send_now(handle)
        return handle

    def _follow(
        self, client: actionlib.ActionClient, handle: GoalHandle[ResultT, FeedbackT]
    ) -> actionlib.ClientGoalHandle:
        """actionlib's handle of a goal the server took from another client: tracked from the status list as
        one of its own (PENDING: a status list without it makes it lost), never sent."""
        manager = client.manager
        action_goal = manager.ActionGoal()
        action_goal.goal_id.id = handle.goal_id
        machine = actionlib.CommStateMachine(
            action_goal, handle.transition, None, manager.send_goal_fn, manager.cancel_fn
        )
        machine.state = _COMM_PENDING
        with manager.list_mutex:
            manager.statuses.append(weakref.ref(machine))
        return actionlib.ClientGoalHandle(machine)

    def send_now(self, handle: GoalHandle[ResultT, FeedbackT]) -> None:
        """Send `handle`'s goal to the server (there now) when it is its turn (GOAL_REQUESTS), else put it in
        line."""
        with self._window:
            admitted = self._unreported < GOAL_REQUESTS and not self._line
            if admitted:
                self._unreported += 1
            elif handle not in self._line:
                self._line.append(handle)
                handle.queue()
        if admitted:
            self._transmit(handle)

    def turn_over(self) -> None:
        """A goal sent was reported (or is over): the next goal in line is sent, in the goals thread (never in
        actionlib's callback, which holds its goal's lock)."""
        with self._window:
            self._unreported -= 1
            following = self._line.pop(0) if self._line and self._unreported < GOAL_REQUESTS else None
            if following is not None:
                self._unreported += 1
        if following is not None:
            _CLOCK.later(0.0, lambda: self._transmit(following))

    def withdraw(self, handle: GoalHandle[ResultT, FeedbackT]) -> None:
        """`handle` no longer waits in line (it is over)."""
        with self._window:
            if handle in self._line:
                self._line.remove(handle)

    def _transmit(self, handle: GoalHandle[ResultT, FeedbackT]) -> None:
        """Send `handle`'s goal (it has its turn)."""
        goal = handle.take_goal()
        if goal is None:
            self.turn_over()  # over meanwhile: the turn goes on
            return
        client = self._client
        if client is None:  # closed by another thread meanwhile
            handle.fail(ServiceUnavailable(self.name, "the client was closed", kind="action"))
            return
        try:
            with self._goals_lock:
                self._next_id = handle.goal_id
                try:
                    if goal is _REJOIN:
                        raw = self._follow(client, handle)
                    else:
                        raw = client.send_goal(goal, transition_cb=handle.transition)
                finally:
                    self._next_id = ""
        except Exception as exc:  # noqa: BLE001 - rospy's words, for whoever follows the goal
            handle.fail(CallFailed(self.name, f"{type(exc).__name__}: {exc}"))
            return
        handle.attach(raw)

    def send(self, goal: GoalT, timeout: float, wait_timeout: float) -> GoalHandle[ResultT, FeedbackT]:
        """Send `goal` and wait until the server takes it up (see the class docstring); feedback is collected
        from the first message on."""
        self._check_goal(goal)
        self.register()
        deadline = time.monotonic() + wait_timeout
        while not self.server_ready():
            if rospy.is_shutdown():
                raise ServiceUnavailable(self.name, "rospy is shutting down", kind="action")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ServiceUnavailable(self.name, f"no action server within {wait_timeout:g} s", kind="action")
            time.sleep(min(POLL_PERIOD, remaining))
        handle = self.start(goal, timeout, wait_timeout)
        handle.wait_taken_up(timeout)
        return handle
