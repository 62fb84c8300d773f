"""A simulated warehouse door controller on ROS 2, for the warehouse demo.

    python -m examples.warehouse.doorsim --door door1 [--travel 0.3] [--rate 20] [--run-for S]

It subscribes to `/<door>/door_controller/command` (std_msgs/Float64: 1.0 open, 0.0 closed; reliable,
transient local, so a latched command arrives) and publishes `/<door>/door_controller/position`
(std_msgs/Float64) at `--rate` Hz while the door moves towards the command in `--travel` seconds (full
stroke). It prints one JSON object per line: `{"event": "ready"}`, then `{"event": "command", "value": v}`
and `{"event": "position", "value": v}` when the door reaches a commanded position. SIGINT/SIGTERM stop it.
"""

from __future__ import annotations

import argparse
import importlib
import json
import signal
import sys
import threading
import time
from collections.abc import Sequence
from types import FrameType
from typing import Any, cast


def emit(event: str, **fields: Any) -> None:
    print(json.dumps({"event": event, **fields}, sort_keys=True), flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m examples.warehouse.doorsim", description=__doc__.split("\n")[0])
    parser.add_argument("--door", default="door1", help="the door's namespace (default door1)")
    parser.add_argument("--travel", type=float, default=0.3, help="seconds from closed to open")
    parser.add_argument("--rate", type=float, default=20.0, help="position publishing rate (Hz)")
    parser.add_argument("--run-for", type=float, default=None, help="exit after this many seconds")
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    Float64: Any = importlib.import_module("std_msgs.msg").Float64  # no type information in the wheel

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)

    node: Any = rclpy.create_node("door_controller", namespace="/" + args.door, context=context)
    state = {"position": 0.0, "target": 0.0, "reported": 0.0}

    def on_command(msg: Any) -> None:
        state["target"] = min(1.0, max(0.0, float(msg.data)))
        emit("command", value=float(msg.data))

    latched = cast(Any, QoSProfile)(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    node.create_subscription(Float64, f"/{args.door}/door_controller/command", on_command, latched)
    publisher = node.create_publisher(Float64, f"/{args.door}/door_controller/position", 10)
    step = 1.0 / max(args.rate, 1.0)
    last = time.monotonic()

    def tick() -> None:
        nonlocal last
        now = time.monotonic()
        delta = (now - last) / max(args.travel, 1e-3)
        last = now
        position, target = state["position"], state["target"]
        if position < target:
            position = min(target, position + delta)
        elif position > target:
            position = max(target, position - delta)
        state["position"] = position
        if position == target and state["reported"] != target:
            state["reported"] = target
            emit("position", value=position)
        publisher.publish(Float64(data=position))

    node.create_timer(step, tick)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    emit("ready", door=args.door)
    deadline = None if args.run_for is None else time.monotonic() + args.run_for
    try:
        while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    return 0


if __name__ == "__main__":
    sys.exit(main())
