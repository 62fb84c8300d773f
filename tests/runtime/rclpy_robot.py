"""A robot made of plain rclpy services, in a context of its own, and the rclpy adaptor of a TD written to disk:
what the edge-node tests on procedures and plain services drive end to end."""

from __future__ import annotations

import json
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from td2adaptor.diagnostics import Diagnostic
from td2adaptor.model import Model
from td2adaptor.runtime import PortTimeout, PortUnavailable
from tests.ros2.common import build_rclpy

Service = tuple[Any, str, Callable[[Any, Any], Any]]  # (type, full name, handler)


class ServiceRobot:
    """An rclpy node with its own context; `serve` starts its services on a two-thread executor."""

    def __init__(self, node_name: str) -> None:
        import rclpy
        from rclpy.context import Context

        self.context = Context()
        rclpy.init(context=self.context)
        self.node: Any = rclpy.create_node(node_name, context=self.context)
        self.lock = threading.Lock()

    def serve(self, services: Sequence[Service]) -> None:
        from rclpy.executors import MultiThreadedExecutor

        self.services = [self.node.create_service(t, name, handler) for t, name, handler in services]
        self.executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def stop(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.thread.join(5)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def generate_rclpy(td: dict[str, Any], interfaces: Path, base: Path) -> tuple[Model, Path, list[Diagnostic]]:
    """Write `td` to `base`, compile it and write its rclpy package under `base/src`: the model, the package's
    folder and the compile diagnostics."""
    path = base / "td.json"
    path.write_text(json.dumps(td), encoding="utf-8")
    result, package = build_rclpy(path, base / "src", interfaces=interfaces)
    assert result.model is not None
    return result.model, package, list(result.diagnostics)


def task_query_answers(port: Any) -> bool:
    """Whether the robot answers a (side-effect free) query of procedure_td's task: a ROS 2 service can be
    discovered before its server matched the client's response reader, losing the first answers."""
    try:
        port.query("TaskComponent", "taskQuery", 0, 1.0)
    except (PortUnavailable, PortTimeout):
        return False
    return True
