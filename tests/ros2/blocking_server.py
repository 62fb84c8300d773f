"""Test servers in their own process: one that never answers, one with std_srvs-style answers.

    python -m tests.ros2.blocking_server silent NAMESPACE
        procedures_msgs/ProcedureQuery at /NAMESPACE/robot_local_control/NavigationComponent/GoToComponent/
        query_state; each callback waits until SIGTERM (at most 60 s): a live server that stays silent.
    python -m tests.ros2.blocking_server late NAMESPACE
        the same service answering with the request's id in `state.header.id`: the first request after
        LATE seconds, the others at once; prints `{"event": "answered", "id": ...}` once each response is sent.
    python -m tests.ros2.blocking_server std NAMESPACE
        std_srvs/Trigger at /NAMESPACE/trigger answering success=False, message "motor fault", and
        std_srvs/SetBool at /NAMESPACE/enable answering success=True, message "enabled: <data>".

Prints `{"event": "ready"}` when the services exist and `{"event": "request"}` per request. The silent mode
and late modes need the RB-1 interfaces importable (tests.ros2.env.child_env).
"""

from __future__ import annotations

import importlib
import json
import signal
import sys
import threading
from types import FrameType
from typing import Any

#: seconds the late server takes to answer its first request
LATE = 1.0


def main(mode: str, namespace: str) -> int:
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, on_signal)
    node: Any = rclpy.create_node("test_server", context=context)

    def never_answer(_request: Any, response: Any) -> Any:
        print(json.dumps({"event": "request"}), flush=True)
        stop.wait(60.0)
        return response

    requests = [0]

    def answer_late_once(request: Any, response: Any) -> Any:
        print(json.dumps({"event": "request"}), flush=True)
        requests[0] += 1
        if requests[0] == 1:
            stop.wait(LATE)
        response.state.header.id = request.header.id
        answered = json.dumps({"event": "answered", "id": request.header.id})
        threading.Timer(0.05, lambda: print(answered, flush=True)).start()  # just after the response went
        return response

    def trigger(_request: Any, response: Any) -> Any:
        print(json.dumps({"event": "request"}), flush=True)
        response.success, response.message = False, "motor fault"
        return response

    def enable(request: Any, response: Any) -> Any:
        print(json.dumps({"event": "request", "data": bool(request.data)}), flush=True)
        response.success, response.message = True, f"enabled: {request.data}"
        return response

    if mode in ("silent", "late"):
        from procedures_msgs.srv import ProcedureQuery

        name = f"/{namespace}/robot_local_control/NavigationComponent/GoToComponent/query_state"
        node.create_service(ProcedureQuery, name, never_answer if mode == "silent" else answer_late_once)
    else:
        std_srvs: Any = importlib.import_module("std_srvs.srv")  # untyped, and not in the RB-1 stubs
        node.create_service(std_srvs.Trigger, f"/{namespace}/trigger", trigger)
        node.create_service(std_srvs.SetBool, f"/{namespace}/enable", enable)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    print(json.dumps({"event": "ready"}), flush=True)
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
