"""Real actionlib servers of test_msgs/Fibonacci for the rospy backend's action tests (Debian's Python).

`fibonacci_server.py NAMESPACE STEP`: under /NAMESPACE,
* `fibonacci`: an actionlib SimpleActionServer; one feedback message per step (the sequence so far, STEP
  seconds apart), then the result. It honours cancel requests between steps (preempted, text "canceled at
  step N"); order 13 ends aborted (text "13 is unlucky").
* `picky`: an actionlib ActionServer that rejects goals with a negative order (text "order must not be
  negative") and succeeds at once otherwise.
* `stuck`: an actionlib ActionServer that never answers a goal (it stays pending).
* `hasty`: an actionlib ActionServer that publishes `order` feedback messages and the result right after the
  last one, with no pause: feedback and result travel on two connections, so the result often arrives first.
* `tardy`: `picky`, but its results go out 0.5 s late, so that a rejection's status comes before its result
  (they travel on two connections: on a loaded machine the status often comes first).
* `burst`: an actionlib ActionServer that publishes `order` feedback messages `[i]` (i = 1 ... order) back to
  back, then the result `[order]`; its publishers queue 5,000 messages (actionlib's default of 50 would drop
  most of a burst before it is sent).
Prints `ready` once all six serve.

`fibonacci_server.py NAMESPACE STEP SLOW`: the same, but `fibonacci`'s feedback and result publishers take a
new subscriber up only SLOW seconds after answering its handshake (rospy does it right after; on a loaded
machine that is late too): a fault injected into this real server, which load cannot produce on cue.
"""

from __future__ import annotations

import sys
import threading
import time

import actionlib
import rospy
import rospy.topics
from test_msgs.msg import FibonacciAction, FibonacciFeedback, FibonacciResult


def main() -> None:
    namespace, step = sys.argv[1], float(sys.argv[2])
    if len(sys.argv) > 3:
        slow_to_take_up(float(sys.argv[3]), {f"/{namespace}/fibonacci/feedback", f"/{namespace}/fibonacci/result"})
    rospy.init_node(f"fibonacci_server_{namespace}", disable_signals=True)  # one per namespace

    def execute(goal: object) -> None:
        sequence = [0, 1]
        for i in range(goal.order):
            if server.is_preempt_requested():
                server.set_preempted(FibonacciResult(sequence=sequence[: i + 1]), f"canceled at step {i}")
                return
            server.publish_feedback(FibonacciFeedback(sequence=sequence[: i + 1]))
            sequence.append(sequence[-1] + sequence[-2])
            time.sleep(step)
        result = FibonacciResult(sequence=sequence[: max(goal.order, 0)])
        if goal.order == 13:
            server.set_aborted(result, "13 is unlucky")
        else:
            server.set_succeeded(result, "done")

    server = actionlib.SimpleActionServer(f"/{namespace}/fibonacci", FibonacciAction, execute, auto_start=False)
    server.start()

    def picky_goal(handle: actionlib.ServerGoalHandle) -> None:
        if handle.get_goal().order < 0:
            handle.set_rejected(FibonacciResult(), "order must not be negative")
        else:
            handle.set_accepted("fine")
            handle.set_succeeded(FibonacciResult(sequence=[0]), "done")

    picky = actionlib.ActionServer(f"/{namespace}/picky", FibonacciAction, picky_goal, auto_start=False)
    picky.start()
    stuck = actionlib.ActionServer(f"/{namespace}/stuck", FibonacciAction, lambda handle: None, auto_start=False)
    stuck.start()

    def hasty_goal(handle: actionlib.ServerGoalHandle) -> None:
        handle.set_accepted("fine")
        sequence = [0, 1]
        for i in range(handle.get_goal().order):
            handle.publish_feedback(FibonacciFeedback(sequence=sequence[: i + 1]))
            sequence.append(sequence[-1] + sequence[-2])
        handle.set_succeeded(FibonacciResult(sequence=sequence[:-2]), "done")

    hasty = actionlib.ActionServer(f"/{namespace}/hasty", FibonacciAction, hasty_goal, auto_start=False)
    hasty.start()
    tardy = actionlib.ActionServer(f"/{namespace}/tardy", FibonacciAction, picky_goal, auto_start=False)
    tardy.start()
    publish_result = tardy.result_pub.publish
    tardy.result_pub.publish = lambda *args: threading.Timer(0.5, publish_result, args).start()

    def burst_goal(handle: actionlib.ServerGoalHandle) -> None:
        handle.set_accepted("bursting")
        order = handle.get_goal().order
        for i in range(1, order + 1):
            handle.publish_feedback(FibonacciFeedback(sequence=[i]))
        handle.set_succeeded(FibonacciResult(sequence=[order]), "done")

    # actionlib reads the queue size when a server starts (ActionServer.initialize, from start()), as a name
    # relative to the node's namespace (here the root): set for the burst server's start, taken away again for
    # servers started later on this master (taken away before start, the burst server had actionlib's 50, and
    # on a loaded machine a burst outran it: 8 of 1,000 lost in the rospy publisher's queue)
    rospy.set_param("actionlib_server_pub_queue_size", 5000)
    burst = actionlib.ActionServer(f"/{namespace}/burst", FibonacciAction, burst_goal, auto_start=False)
    burst.start()
    rospy.delete_param("actionlib_server_pub_queue_size")
    print("ready", flush=True)
    rospy.spin()


def slow_to_take_up(delay: float, topics: set[str]) -> None:
    """Make the publishers of `topics` add a new subscriber `delay` seconds after its handshake."""
    add_connection = rospy.topics._PublisherImpl.add_connection

    def late(self: rospy.topics._PublisherImpl, connection: object) -> bool:
        if self.resolved_name in topics:
            time.sleep(delay)
        return add_connection(self, connection)

    rospy.topics._PublisherImpl.add_connection = late


if __name__ == "__main__":
    main()
