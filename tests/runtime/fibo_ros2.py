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
    from test_msgs.action import Fibonacci

    rclpy.init()
    node: Any = rclpy.create_node("fibo_robot")
    lock = threading.Lock()

    def on_goal(goal: Any) -> Any:
        return GoalResponse.REJECT if goal.order < 0 else GoalResponse.ACCEPT

    def make_execute(ns: str) -> Any:
        def execute(handle: Any) -> Any:
            order = handle.request.order
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

    group = ReentrantCallbackGroup()
    servers = [
        ActionServer(
            node,
            Fibonacci,
            f"/{ns}/fibonacci",
            execute_callback=make_execute(ns),
            goal_callback=on_goal,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
            callback_group=group,
        )
        for ns in namespaces
    ]
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    emit(event="ready", servers=len(servers))
    try:
        executor.spin()
    finally:
        executor.shutdown()


if __name__ == "__main__":
    serve(sys.argv[1:])
