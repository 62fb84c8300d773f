"""A ROS 2 robot whose long task is an action: a real `rclpy.action.ActionServer` of test_msgs/action/Fibonacci.

Run as `python -m tests.runtime.fibo_ros2 NAMESPACE...` (one server per namespace, at /<ns>/fibonacci); it
prints JSON event lines on stdout (`ready`, `goal`, `feedback` with the message sent, `end`). What it does
depends on the goal's order (see `behaviour`): the tests and the server agree through these numbers only.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from typing import Any

#: seconds between feedback messages (also after the last one, before the result)
STEP = 0.05
#: orders with a meaning: rejected below 0, aborted after two messages, slow (until canceled)
ABORT = 77
SLOW = 1000
SLOW_STEP = 0.2
#: orders from FAST on: FAST_STEP apart, (order - FAST) messages (benchmarks)
FAST = 10000
FAST_STEP = 0.001
#: orders from BURST on: (order - BURST) messages published back to back, message i carrying [i] (so that each
#: one differs), then the result [order - BURST]
BURST = 20000
#: the longest burst the server keeps for a client that has not taken it yet (its feedback publisher's depth)
BURST_MOST = 1000


def sequence(order: int) -> list[int]:
    """The first `order + 1` Fibonacci numbers (at least [0, 1])."""
    seq = [0, 1]
    while len(seq) < order + 1:
        seq.append(seq[-1] + seq[-2])
    return seq[: max(order + 1, 2)]


def emit(**event: Any) -> None:
    print(json.dumps(event), flush=True)


def serve(namespaces: list[str]) -> None:
    import rclpy
    from rclpy.action import ActionServer, CancelResponse, GoalResponse
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from test_msgs.action import Fibonacci

    rclpy.init()
    node: Any = rclpy.create_node("fibo_robot")
    lock = threading.Lock()

    def on_goal(goal: Any) -> Any:
        return GoalResponse.REJECT if goal.order < 0 else GoalResponse.ACCEPT

    def make_execute(ns: str) -> Any:
        def execute(handle: Any) -> Any:
            order = handle.request.order
            if order >= BURST:
                return burst(ns, handle, order - BURST)
            steps = 10**6 if order == SLOW else order - FAST if order >= FAST else order
            step = SLOW_STEP if order == SLOW else FAST_STEP if order >= FAST else STEP
            emit(event="goal", ns=ns, order=order)
            result = Fibonacci.Result()
            for i in range(1, steps + 1):
                if handle.is_cancel_requested:
                    handle.canceled()
                    result.sequence = sequence(min(i - 1, 40))
                    emit(event="end", ns=ns, status="canceled")
                    return result
                feedback = Fibonacci.Feedback()
                feedback.sequence = sequence(min(i, 40))
                with lock:
                    handle.publish_feedback(feedback)
                    emit(event="feedback", ns=ns, i=i, sequence=list(feedback.sequence))
                if order == ABORT and i == 2:
                    handle.abort()
                    result.sequence = sequence(i)
                    emit(event="end", ns=ns, status="aborted")
                    return result
                time.sleep(step)
            handle.succeed()
            result.sequence = sequence(min(order, 40))
            emit(event="end", ns=ns, status="succeeded")
            return result

        return execute

    def burst(ns: str, handle: Any, count: int) -> Any:
        emit(event="goal", ns=ns, order=BURST + count)
        for i in range(1, count + 1):
            feedback = Fibonacci.Feedback()
            feedback.sequence = [i]
            handle.publish_feedback(feedback)
        emit(event="burst", ns=ns, count=count)
        handle.succeed()
        result = Fibonacci.Result()
        result.sequence = [count]
        emit(event="end", ns=ns, status="succeeded")
        return result

    group = ReentrantCallbackGroup()
    feedback_qos = QoSProfile(depth=BURST_MOST, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
    servers = [
        ActionServer(
            node,
            Fibonacci,
            f"/{ns}/fibonacci",
            execute_callback=make_execute(ns),
            goal_callback=on_goal,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
            callback_group=group,
            feedback_pub_qos_profile=feedback_qos,  # a burst is kept until our client has it
        )
        for ns in namespaces
    ]
    executor = MultiThreadedExecutor(num_threads=max(4, len(namespaces) + 2))  # each running goal holds one
    executor.add_node(node)
    emit(event="ready", servers=len(servers))
    try:
        executor.spin()
    finally:
        executor.shutdown()


if __name__ == "__main__":
    serve(sys.argv[1:])
