"""A ROS 1 robot whose long task is an action: a real actionlib ActionServer of test_msgs/Fibonacci.

Run under the ROS 1 interpreter (Debian's /usr/bin/python3) with the genpy modules of tests/data/actions and
the repository on PYTHONPATH: `fibo_ros1.py NAMESPACE`. It behaves like tests.runtime.fibo_ros2 (the same
orders mean the same things: negative → rejected with the server's words, ABORT → aborted after two
feedback messages, SLOW → runs until canceled) and prints the same JSON event lines.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from typing import Any

import actionlib
import rospy
from test_msgs.msg import FibonacciAction, FibonacciFeedback, FibonacciResult

from tests.runtime.fibo_ros2 import ABORT, BURST, BURST_MOST, SLOW, SLOW_STEP, STEP, sequence


def emit(**event: Any) -> None:
    print(json.dumps(event), flush=True)


def main() -> None:
    namespace = sys.argv[1]
    rospy.init_node("fibo_robot", anonymous=True, disable_signals=True)
    lock = threading.Lock()

    def burst(handle: Any, count: int) -> None:
        emit(event="goal", ns=namespace, order=BURST + count)
        for i in range(1, count + 1):
            handle.publish_feedback(FibonacciFeedback(sequence=[i]))
        emit(event="burst", ns=namespace, count=count)
        handle.set_succeeded(FibonacciResult(sequence=[count]), "done")
        emit(event="end", ns=namespace, status="succeeded")

    def execute(handle: Any) -> None:
        order = handle.get_goal().order
        if order >= BURST:
            burst(handle, order - BURST)
            return
        steps = 10**6 if order == SLOW else order
        step = SLOW_STEP if order == SLOW else STEP
        emit(event="goal", ns=namespace, order=order)
        for i in range(1, steps + 1):
            if handle.get_goal_status().status in (6, 7):  # PREEMPTING, RECALLING: a cancel was asked
                handle.set_canceled(FibonacciResult(sequence=sequence(min(i - 1, 40))), "canceled on request")
                emit(event="end", ns=namespace, status="canceled")
                return
            with lock:
                handle.publish_feedback(FibonacciFeedback(sequence=sequence(min(i, 40))))
                emit(event="feedback", ns=namespace, i=i, sequence=sequence(min(i, 40)))
            if order == ABORT and i == 2:
                # ends the goal right after publishing, as real servers do: feedback and result travel on two
                # TCPROS connections, so the result often arrives first, and the terminal event must still
                # follow that feedback (actionlib's own client would drop it; docs/binding.md)
                handle.set_aborted(FibonacciResult(sequence=sequence(i)), f"{ABORT} is unlucky")
                emit(event="end", ns=namespace, status="aborted")
                return
            time.sleep(step)
        handle.set_succeeded(FibonacciResult(sequence=sequence(min(order, 40))), "done")  # int32: as on ROS 2
        emit(event="end", ns=namespace, status="succeeded")

    def on_goal(handle: Any) -> None:
        if handle.get_goal().order < 0:
            handle.set_rejected(FibonacciResult(), "order must not be negative")
            return
        handle.set_accepted("on it")
        threading.Thread(target=execute, args=(handle,), daemon=True).start()

    # actionlib's server publishes through queues of 50 messages by default: a burst would overflow them
    rospy.set_param("actionlib_server_pub_queue_size", BURST_MOST)
    server = actionlib.ActionServer(
        f"/{namespace}/fibonacci", FibonacciAction, on_goal, lambda handle: None, auto_start=False
    )
    server.start()
    emit(event="ready", servers=1)
    rospy.spin()


if __name__ == "__main__":
    main()
