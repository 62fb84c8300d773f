"""A ROS 2 action server for the scaffold tests: test_msgs/action/Fibonacci at /NAMESPACE/fibonacci.

    python -m tests.scaffold.fibonacci_server NAMESPACE

Prints `{"event": "ready"}` once the server exists; SIGTERM stops it.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
from types import FrameType
from typing import Any


def main(namespace: str) -> int:
    import rclpy
    from rclpy.action import ActionServer
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from test_msgs.action import Fibonacci

    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, on_signal)
    node: Any = rclpy.create_node("fibonacci_server", namespace="/" + namespace, context=context)

    def execute(goal_handle: Any) -> Any:
        sequence = [0, 1]
        for _ in range(max(0, goal_handle.request.order - 1)):
            sequence.append(sequence[-1] + sequence[-2])
        goal_handle.succeed()
        return Fibonacci.Result(sequence=sequence[: goal_handle.request.order + 1])

    server = ActionServer(node, Fibonacci, "fibonacci", execute)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    print(json.dumps({"event": "ready"}), flush=True)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)
    finally:
        server.destroy()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
