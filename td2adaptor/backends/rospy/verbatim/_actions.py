"""Run-time support of ROS 1 actions (actionlib): goals sent over `<name>/goal`, followed on `<name>/status`,
`<name>/feedback` and `<name>/result`, cancelled on `<name>/cancel`. Copied only into packages with actions,
which then need actionlib (Debian's python3-actionlib).

Mirrors the ROS 2 (rclpy) adaptor's actions: `ActionGoalClient.send` returns a `GoalHandle` with the same
members, and no method waits longer than its timeout, whatever the robot does. ROS 1 acknowledges a goal only
through the status topic, so `send` waits for the server to take the goal up (or reject it) instead of an
acceptance reply. rospy runs callbacks in its own threads, so any thread may block here.
"""

from __future__ import annotations

import http.client
import threading
import time
import weakref
import xmlrpc.client
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any, Generic, TypeVar, cast

import actionlib
import rospy

from ._runtime import require_node
from .common import Callbacks, check_timeout
from .errors import (
    CallFailed,
    CallTimeout,
    GoalAborted,
    GoalCanceled,
    GoalRejected,
    InvalidMessage,
    ServiceUnavailable,
)

GoalT = TypeVar("GoalT")
ResultT = TypeVar("ResultT")
FeedbackT = TypeVar("FeedbackT")

#: how often a wait for an action server re-checks its connections
POLL_PERIOD = 0.02
#: how long a wait for an action server gives the server's XML-RPC API to answer getBusInfo
BUS_INFO_TIMEOUT = 2.0
#: how often a wait on a goal checks that the action server is still connected
LIVENESS_PERIOD = 0.1

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
#: actionlib's CommState.DONE: the result arrived (or the goal was lost)
_DONE = 7

#: how many feedback messages a goal handle keeps for iterators that fall behind (older ones are dropped)
FEEDBACK_BUFFER = 1000


class GoalHandle(Generic[ResultT, FeedbackT]):
    """One goal sent to a ROS 1 action server that took it up.

    `goal_id` is actionlib's goal id (a string), `status` the goal's latest status ("pending", "executing",
    "canceling", "succeeded", "canceled", "aborted", "rejected", "lost"; "unknown" before the first report).
    Feedback arrives in rospy's receive thread: `on_feedback(callback)` calls a callback with each message,
    `feedback(timeout=...)` iterates over them in the caller's thread until the goal ends. Feedback and result
    travel on two connections, so a message the server published right before the result may arrive just
    after it: it still reaches the callbacks and the buffer (actionlib's own client would drop it).
    `result(timeout=...)` waits for the end; `cancel(timeout=...)` asks the server to cancel the goal. No
    method waits longer than its timeout, and a wait ends early with ServiceUnavailable when the action server
    goes away (ROS 1 would not tell otherwise: a dead server just stops publishing).
    """

    def __init__(self, action: str, timeout: float, server_alive: Callable[[], bool] = lambda: True) -> None:
        self.action = action
        self.timeout = timeout
        self._server_alive = server_alive
        self.goal_id = ""
        self._handle: actionlib.ClientGoalHandle | None = None  # set once sent
        self._cond = threading.Condition()
        self._feedback: deque[FeedbackT] = deque(maxlen=FEEDBACK_BUFFER)
        self._received = 0  # feedback messages received so far (also those dropped from the buffer)
        self._callbacks: Callbacks[FeedbackT] = Callbacks()
        self._code: int | None = None  # the latest GoalStatus code the server reported
        self._text = ""  # the server's words with it
        self._done = False
        self._result: Any = None

    # called in rospy's threads (actionlib's callbacks)

    def transition(self, handle: actionlib.ClientGoalHandle) -> None:
        """A change of the goal's state (actionlib's transition callback; not for callers)."""
        code = int(handle.get_goal_status())
        text = str(handle.get_goal_status_text())
        done = int(handle.get_comm_state()) == _DONE
        result = handle.get_result() if done else None
        with self._cond:
            self._code, self._text = code, text
            if done and not self._done:
                self._done, self._result = True, result
            self._cond.notify_all()

    def deliver(self, feedback: FeedbackT) -> None:
        """One feedback message of this goal (from ActionGoalClient's feedback subscription; not for callers)."""
        with self._cond:
            self._feedback.append(feedback)
            self._received += 1
            self._cond.notify_all()
        for callback in self._callbacks.current():
            try:
                callback(feedback)
            except Exception as exc:  # one failing callback must not starve the others
                rospy.logerr(f"{self.action}: feedback callback {callback!r} failed: {exc!r}")

    # the caller's side

    @property
    def status(self) -> str:
        """The goal's latest status (see the class docstring)."""
        with self._cond:
            return "unknown" if self._code is None else GOAL_STATUS.get(self._code, "unknown")

    @property
    def reason(self) -> str:
        """The server's words with the latest status (actionlib's status text; often empty)."""
        with self._cond:
            return self._text

    @property
    def done(self) -> bool:
        """Whether the goal has ended (succeeded, canceled, aborted, rejected or lost)."""
        with self._cond:
            return self._done

    @property
    def feedback_received(self) -> int:
        """How many feedback messages the goal has received so far (also those no longer buffered): as many
        as `feedback()` yields at once, without waiting, when nothing was dropped."""
        with self._cond:
            return self._received

    def on_feedback(self, callback: Callable[[FeedbackT], None]) -> Callable[[], None]:
        """Call `callback` with every feedback message from now on, in rospy's receive thread; returns a
        function that removes it again."""
        return self._callbacks.add(callback)

    def feedback(self, timeout: float | None = None) -> Iterator[FeedbackT]:
        """The goal's feedback messages, from the first one received, until the goal ends.

        Waits at most `timeout` seconds (default: the component's timeout) for each next message or for the
        end; raises CallTimeout when neither came by then. Messages arrived while the loop body ran are not
        lost (up to FEEDBACK_BUFFER of them).
        """
        wait = check_timeout(self.timeout if timeout is None else timeout, "timeout")
        position = 0
        while True:
            with self._cond:
                if position >= self._received and not self._done:
                    self._wait_beyond(position, wait)
                if position < self._received:
                    oldest = self._received - len(self._feedback)
                    position = max(position, oldest)
                    item = self._feedback[position - oldest]
                    position += 1
                elif self._done:
                    return
                else:
                    raise CallTimeout(self.action, wait)
            yield item

    def _wait_beyond(self, position: int, wait: float) -> None:
        """Wait at most `wait` seconds for a feedback message after `position`, or for the end (lock held)."""
        self._wait_until(lambda: position < self._received or self._done, wait)

    def _wait_until(self, predicate: Callable[[], bool], wait: float) -> None:
        """Wait (lock held) at most `wait` seconds for `predicate`; ServiceUnavailable when the server is seen
        gone twice in a row meanwhile (once could be a connection being remade)."""
        deadline = time.monotonic() + wait
        missing = 0
        while not predicate():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            self._cond.wait(min(remaining, LIVENESS_PERIOD))
            missing = 0 if predicate() or self._server_alive() else missing + 1
            if missing >= 2:
                raise ServiceUnavailable(self.action, "the action server went away during the goal", kind="action")

    def result(self, timeout: float | None = None) -> ResultT:
        """Wait at most `timeout` seconds (default: the component's timeout) for the goal to end; its result.

        Raises GoalAborted or GoalCanceled when it did not succeed (the result the server sent is the error's
        `response`, its status text the `message`), GoalRejected when the server rejected a goal it had left
        pending, CallTimeout when it did not end in time (the goal goes on: wait again or cancel()),
        ServiceUnavailable when the action server went away meanwhile.
        """
        wait = check_timeout(self.timeout if timeout is None else timeout, "timeout")
        with self._cond:
            self._wait_until(lambda: self._done, wait)
            if not self._done:
                raise CallTimeout(self.action, wait)
            code, text, result = self._code, self._text, self._result
        if code == _SUCCEEDED:
            return cast(ResultT, result)
        if code == _ABORTED:
            raise GoalAborted(self.action, result, text)
        if code in (_PREEMPTED, _RECALLED):
            raise GoalCanceled(self.action, result, text)
        if code == _REJECTED:
            raise GoalRejected(self.action, text)
        raise CallFailed(self.action, f"the goal was lost (status {code}: the server forgot it)", result)

    def cancel(self, timeout: float | None = None) -> bool:
        """Ask the server to cancel the goal and wait at most `timeout` seconds (default: the component's) for
        it to take the request up; whether it did (False: the goal had already ended, or ended otherwise first).
        The goal then ends canceled (result() raises GoalCanceled) unless it ended otherwise first."""
        wait = check_timeout(self.timeout if timeout is None else timeout, "timeout")
        if self.done or self._handle is None:
            return False
        self._handle.cancel()  # never under self._cond: actionlib calls _transition under its own lock
        canceling = (_PREEMPTING, _RECALLING, _PREEMPTED, _RECALLED)
        with self._cond:
            self._wait_until(lambda: self._code in canceling or self._done, wait)
            if self._code in canceling:
                return True
            if self._done:
                return False
        raise CallTimeout(self.action + " (cancel)", wait)

    def attach(self, handle: actionlib.ClientGoalHandle) -> None:
        """The goal was sent as `handle` (called by ActionGoalClient; not for callers)."""
        self._handle = handle
        self.goal_id = str(handle.comm_state_machine.action_goal.goal_id.id)

    def wait_taken_up(self, wait: float) -> bool:
        """Wait at most `wait` seconds for the server to start the goal, end it or reject it; whether it at least
        reported the goal (as pending) by then."""
        with self._cond:
            self._cond.wait_for(lambda: self._done or self._code not in (None, _PENDING), wait)
            return self._code is not None


def _publishers(subscription: rospy.Subscriber) -> set[str]:
    """The XML-RPC URIs of the nodes `subscription` is connected to (rospy keeps them as endpoint ids)."""
    return {str(connection.endpoint_id) for connection in list(subscription.impl.connections)}


def _topics_sent_to(uri: str, caller_id: str) -> set[str] | None:
    """The topics the node at `uri` publishes to `caller_id` by its getBusInfo (empty when it cannot be
    reached yet), or None when it has no getBusInfo (then nothing more than the connection counts is known)."""
    try:
        proxy = xmlrpc.client.ServerProxy(uri, transport=_TimedTransport(BUS_INFO_TIMEOUT))
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


class _TimedTransport(xmlrpc.client.Transport):
    """An XML-RPC transport whose connections time out (xmlrpc.client's default waits forever)."""

    def __init__(self, timeout: float) -> None:
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host: Any) -> http.client.HTTPConnection:
        connection = super().make_connection(host)
        connection.timeout = self._timeout
        return connection


class ActionGoalClient(Generic[GoalT, ResultT, FeedbackT]):
    """One ROS 1 action client (`actionlib.ActionClient`) that never waits forever.

    `send` waits at most `wait_timeout` for an action server (ServiceUnavailable), then at most `timeout` for
    the server to take the goal up: GoalRejected when it rejects it, CallTimeout when it never reports the goal
    (the goal is then cancelled). A goal the server reports but leaves pending is returned as it is.
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
        self._goals: weakref.WeakValueDictionary[str, GoalHandle[ResultT, FeedbackT]] = weakref.WeakValueDictionary()
        self._goals_lock = threading.Lock()  # held while a goal is sent and filed, so its feedback finds it
        self._servers_seen: set[str] = set()  # XML-RPC URIs of servers known to publish to this node

    def register(self) -> None:
        """Create the action client (its goal/cancel publishers and status/feedback/result subscribers)."""
        if self._client is None:
            require_node()
            with self._lock:
                if self._client is None:
                    client = actionlib.ActionClient(self.name, self._action_class)
                    topic = client.feedback_sub.resolved_name
                    self._feedback_sub = rospy.Subscriber(topic, client.ActionFeedback, self._on_feedback)
                    self._client = client

    def _on_feedback(self, message: Any) -> None:
        """A message on the feedback topic (rospy's receive thread): to its goal's handle, if it is ours."""
        with self._goals_lock:
            handle = self._goals.get(str(message.status.goal_id.id))
        if handle is not None:
            handle.deliver(cast(FeedbackT, message.feedback))

    def close(self) -> None:
        """Unregister the client's publishers and subscribers; register() (or send) sets them up again."""
        with self._lock:
            client, self._client = self._client, None
            subscription, self._feedback_sub = self._feedback_sub, None
        if subscription is not None:
            subscription.unregister()
        if client is not None:
            client.stop()

    def server_ready(self) -> bool:
        """Whether an action server is connected on all five topics and has reported its status."""
        client = self._client
        if client is None or client.last_status_msg is None:
            return False
        parts = (client.pub_goal, client.pub_cancel, client.status_sub, client.result_sub, client.feedback_sub)
        return all(part.get_num_connections() > 0 for part in parts) and self._server_sends_to_us(client)

    def _server_sends_to_us(self, client: actionlib.ActionClient) -> bool:
        """Whether the servers' feedback and result publishers have taken this node's subscriptions up.

        rospy (and roscpp) count a subscription as connected once the publisher has answered its handshake,
        but the publisher adds it to its own list only after that: a message published in between (a goal's
        first feedback, a quick result) never reaches us. The server's getBusInfo tells; asked once per
        server process (its XML-RPC URI, new on every start)."""
        servers = _publishers(client.feedback_sub) & _publishers(client.result_sub)
        me = rospy.get_caller_id()
        topics = {client.feedback_sub.resolved_name, client.result_sub.resolved_name}
        for uri in servers - self._servers_seen:
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

    def send(self, goal: GoalT, timeout: float, wait_timeout: float) -> GoalHandle[ResultT, FeedbackT]:
        """Send `goal` (see the class docstring); feedback is collected from the first message on."""
        if not isinstance(goal, self._goal_class):
            expected = getattr(self._goal_class, "_type", self._goal_class.__name__)
            raise InvalidMessage(f"{self.name}: expected {expected}, not {type(goal).__name__}")
        self.register()
        deadline = time.monotonic() + wait_timeout
        while not self.server_ready():
            if rospy.is_shutdown():
                raise ServiceUnavailable(self.name, "rospy is shutting down", kind="action")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise ServiceUnavailable(self.name, f"no action server within {wait_timeout:g} s", kind="action")
            time.sleep(min(POLL_PERIOD, remaining))
        handle: GoalHandle[ResultT, FeedbackT] = GoalHandle(self.name, timeout, self.server_connected)
        client = self._client
        if client is None:  # closed by another thread meanwhile
            raise ServiceUnavailable(self.name, "the client was closed", kind="action")
        with self._goals_lock:
            raw = client.send_goal(goal, transition_cb=handle.transition)
            handle.attach(raw)
            self._goals[handle.goal_id] = handle
        if not handle.wait_taken_up(timeout):
            raw.cancel()  # the server may take it up later: nobody would follow it
            if not self.server_ready():
                raise ServiceUnavailable(self.name, f"the server went away within {timeout:g} s", kind="action")
            raise CallTimeout(self.name, timeout)
        if handle.status == "rejected":
            raise GoalRejected(self.name, handle.reason)
        return handle
