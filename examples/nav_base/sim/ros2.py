"""The simulated nav_base on ROS 2 (rclpy): `core.BaseSim` served with real action servers, services and topics.

    .venv/bin/python -m examples.nav_base.sim.ros2 --namespace nav_base_a [--namespace nav_base_b ...]

    --speed M_S         driving speed (default 1.0 m/s); --dock-time S how long a docking takes (default 0.5)
    --feedback-rate HZ  action feedback messages per second while a goal runs (default 10)
    --rate HZ           odom, battery_state and scan publishing rate (default 10)
    --run-for S         exit after S seconds (default: until SIGINT/SIGTERM)
    --prefix DIR        an install prefix holding nav_base_msgs (repeatable); without one, and when they are
                        not importable already, they are built once with CMake into .cache/ros2-interfaces

Per robot NS (one node each, all in this process, spun by one multi-threaded executor):

* actions (`rclpy.action.ActionServer`): `/NS/navigate_to_pose` (nav_base_msgs/action/NavigateToPose;
  feedback while driving: current pose, distance and time remaining), `/NS/dock_robot` (DockRobot; feedback
  state INITIAL_PERCEPTION then CONTROLLING), `/NS/undock_robot` (UndockRobot). A goal is rejected while
  another task runs, for a pose outside the map, with the motors off; a cancel stops the base where it is;
  a docking that cannot succeed is aborted with the error code and message of `core.py`;
* services: `/NS/stop` (std_srvs/Trigger: cancels what runs; its goal ends aborted), `/NS/enable_motors`
  (std_srvs/SetBool);
* topics: subscribes `/NS/cmd_vel` (geometry_msgs/Twist, held for 0.5 s), publishes `/NS/odom`
  (nav_msgs/Odometry), `/NS/battery_state` (sensor_msgs/BatteryState), `/NS/scan` (sensor_msgs/LaserScan,
  best effort).

It prints one JSON object per line on stdout: `{"event": "ready", ...}` once everything is up, then
`{"event": "goal", ...}` for each goal accepted or rejected (with the reason), `{"event": "result", ...}` for each
goal that ended, `{"event": "call", ...}` for each service call.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import Any

from examples.nav_base.sim import core
from examples.robotnik_rb1.sim.ros2 import emit, use_prefix

CMD_HOLD = 0.5  # seconds a cmd_vel message keeps driving


def stamp_of(node: Any) -> Any:
    return node.get_clock().now().to_msg()


def duration_msg(seconds: float) -> Any:
    from builtin_interfaces.msg import Duration

    whole = math.floor(seconds)
    return Duration(sec=int(whole), nanosec=int((seconds - whole) * 1e9))


class BaseNode:
    """One simulated base: a node in namespace `ns` serving core.BaseSim."""

    def __init__(self, context: Any, ns: str, base: core.BaseSim, *, rate: float, feedback_rate: float) -> None:
        import rclpy
        from geometry_msgs.msg import Twist
        from nav_base_msgs.action import DockRobot, NavigateToPose, UndockRobot
        from nav_msgs.msg import Odometry
        from rclpy.action import ActionServer, CancelResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import BatteryState, LaserScan
        from std_srvs.srv import SetBool, Trigger

        self.ns = ns
        self.base = base
        self.period = 1.0 / feedback_rate
        self.node: Any = rclpy.create_node("nav_base_sim", namespace="/" + ns, context=context)
        group = ReentrantCallbackGroup()
        # the task each accepted goal started, by the goal message (rclpy hands the execute callback the same
        # object it gave the goal callback, which sees no goal id)
        self.tasks: dict[int, core.Task] = {}
        self.servers = []
        for name, kind, action in (
            ("navigate_to_pose", core.NAVIGATE, NavigateToPose),
            ("dock_robot", core.DOCK, DockRobot),
            ("undock_robot", core.UNDOCK, UndockRobot),
        ):
            self.servers.append(
                ActionServer(
                    self.node,
                    action,
                    f"/{ns}/{name}",
                    execute_callback=self._execute(name, kind, action),
                    goal_callback=self._on_goal(name, kind),
                    cancel_callback=lambda _handle: CancelResponse.ACCEPT,
                    callback_group=group,
                )
            )
        self.node.create_service(Trigger, f"/{ns}/stop", self._stop, callback_group=group)
        self.node.create_service(SetBool, f"/{ns}/enable_motors", self._enable, callback_group=group)
        self.cmd: tuple[float, float, float] | None = None  # linear, angular, received at
        self.node.create_subscription(Twist, f"/{ns}/cmd_vel", self._on_cmd, 10, callback_group=group)
        self.odom_pub = self.node.create_publisher(Odometry, f"/{ns}/odom", 10)
        self.battery_pub = self.node.create_publisher(BatteryState, f"/{ns}/battery_state", 10)
        sensor_qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.scan_pub = self.node.create_publisher(LaserScan, f"/{ns}/scan", sensor_qos)
        self.last_tick = time.monotonic()
        self.node.create_timer(1.0 / rate, self.publish, callback_group=group)

    # -- actions -------------------------------------------------------------------------------------------

    def _on_goal(self, name: str, kind: str) -> Any:
        from rclpy.action import GoalResponse

        def decide(goal_request: Any) -> Any:
            # the task starts here, so that the busy check and the start are one step
            try:
                task = self._start(kind, goal_request)
            except core.Refused as exc:
                emit("goal", robot=self.ns, action=name, accepted=False, reason=str(exc))
                self.node.get_logger().info(f"{name} goal rejected: {exc}")
                return GoalResponse.REJECT
            self.tasks[id(goal_request)] = task
            emit("goal", robot=self.ns, action=name, accepted=True)
            return GoalResponse.ACCEPT

        return decide

    def _start(self, kind: str, goal: Any) -> core.Task:
        if kind == core.NAVIGATE:
            p = goal.pose.pose
            return self.base.navigate(p.position.x, p.position.y, core.yaw_of(p.orientation.z, p.orientation.w))
        if kind == core.DOCK:
            dock_id = goal.dock_id if goal.use_dock_id else self._cart_at(goal.dock_pose.pose.position)
            return self.base.dock(dock_id)
        return self.base.undock()

    def _cart_at(self, position: Any) -> str:
        """The cart standing at a dock pose (for goals with use_dock_id false); '' when none does."""
        for cart, (x, y) in self.base.carts.items():
            if math.hypot(x - position.x, y - position.y) <= core.DOCK_RADIUS:
                return cart
        return ""

    def _execute(self, name: str, kind: str, action: Any) -> Any:
        def run(handle: Any) -> Any:
            task = self.tasks.pop(id(handle.request))
            while not task.done:
                if handle.is_cancel_requested:
                    task.cancel()
                    break
                feedback = self._feedback(kind, action, task)
                if feedback is not None:
                    handle.publish_feedback(feedback)
                time.sleep(self.period)
            result = action.Result()
            if hasattr(result, "error_msg"):
                result.error_msg = task.message
            if hasattr(result, "error_code"):
                result.error_code = task.error_code if task.state == core.FAILED else 0
            if hasattr(result, "success"):
                result.success = task.state == core.SUCCEEDED
            if task.state == core.SUCCEEDED:
                handle.succeed()
            elif task.state == core.CANCELED and handle.is_cancel_requested:
                handle.canceled()
            else:  # failed, or stopped by the stop service / the motors going off
                if hasattr(result, "error_code") and not result.error_code:
                    result.error_code = core.NAV_UNKNOWN if kind == core.NAVIGATE else core.DOCK_NOT_VALID
                handle.abort()
            emit("result", robot=self.ns, action=name, state=task.state, error_code=result.error_code)
            return result

        return run

    def _feedback(self, kind: str, action: Any, task: core.Task) -> Any:
        if kind == core.UNDOCK:
            return None  # UndockRobot has no feedback fields
        feedback = action.Feedback()
        if kind == core.NAVIGATE:
            x, y, theta = task.pose()
            pose = feedback.current_pose
            pose.header.stamp = stamp_of(self.node)
            pose.header.frame_id = "map"
            pose.pose.position.x, pose.pose.position.y = x, y
            pose.pose.orientation.z, pose.pose.orientation.w = core.quaternion_z_w(theta)
            feedback.navigation_time = duration_msg(task.elapsed())
            feedback.estimated_time_remaining = duration_msg(task.time_left())
            feedback.distance_remaining = task.remaining()
        else:
            first_half = task.progress() < 0.5
            feedback.state = core.DOCK_INITIAL_PERCEPTION if first_half else core.DOCK_CONTROLLING
            feedback.docking_time = duration_msg(task.elapsed())
        return feedback

    # -- services and topics -------------------------------------------------------------------------------

    def _stop(self, _request: Any, response: Any) -> Any:
        response.success, response.message = self.base.stop()
        emit("call", robot=self.ns, service="stop", message=response.message)
        return response

    def _enable(self, request: Any, response: Any) -> Any:
        response.success, response.message = self.base.set_motors(bool(request.data))
        emit("call", robot=self.ns, service="enable_motors", data=bool(request.data))
        return response

    def _on_cmd(self, msg: Any) -> None:
        self.cmd = (msg.linear.x, msg.angular.z, time.monotonic())

    def publish(self) -> None:
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import BatteryState, LaserScan

        now = time.monotonic()
        dt, self.last_tick = now - self.last_tick, now
        if self.cmd is not None and now - self.cmd[2] <= CMD_HOLD:
            self.base.drive(self.cmd[0], self.cmd[1], min(dt, CMD_HOLD))
        stamp = stamp_of(self.node)
        x, y, theta = self.base.pose()
        linear, angular = self.base.velocity()

        odom = Odometry()
        odom.header.stamp = stamp
        odom.header.frame_id = "odom"
        odom.child_frame_id = "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = core.quaternion_z_w(theta)
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = linear, angular
        self.odom_pub.publish(odom)

        battery = BatteryState()
        battery.header.stamp = stamp
        battery.percentage = float(self.base.battery)
        battery.voltage = 22.0 + 4.0 * self.base.battery
        battery.present = True
        battery.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        self.battery_pub.publish(battery)

        scan = LaserScan()
        scan.header.stamp = stamp
        scan.header.frame_id = "laser"
        scan.angle_min, scan.angle_max = -math.pi / 2, math.pi / 2
        scan.angle_increment = math.pi / (core.LASER_BEAMS - 1)
        scan.range_min, scan.range_max = 0.05, core.LASER_MAX
        scan.ranges = self.base.laser()
        self.scan_pub.publish(scan)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m examples.nav_base.sim.ros2", description=__doc__.split("\n")[0])
    parser.add_argument("--namespace", action="append", help="robot namespace (repeatable; default nav_base_a)")
    parser.add_argument("--speed", type=float, default=1.0, help="driving speed (m/s)")
    parser.add_argument("--dock-time", type=float, default=0.5, help="seconds a docking takes")
    parser.add_argument("--feedback-rate", type=float, default=10.0, help="action feedback messages per second")
    parser.add_argument("--rate", type=float, default=10.0, help="odom/battery/scan publishing rate (Hz)")
    parser.add_argument("--run-for", type=float, default=None, help="exit after this many seconds")
    parser.add_argument("--prefix", action="append", default=[], help="install prefix of nav_base_msgs")
    return parser.parse_args(argv)


def ensure_interfaces(prefixes: Sequence[str]) -> str | None:
    """Make nav_base_msgs importable: the given prefixes, or else the source checkout's build of them (made
    with CMake on first use, cached in .cache/ros2-interfaces). The reason when that cannot be done."""
    import importlib.util

    if importlib.util.find_spec("rclpy") is None:
        return "ROS 2 Jazzy (rclpy) is not installed: bash .ci/setup-ros2.sh, or pip install -e '.[ros2]'"
    for prefix in prefixes:
        use_prefix(Path(prefix))
    if prefixes or importlib.util.find_spec("nav_base_msgs") is not None:
        return None
    from td2adaptor.support import ros2build

    repo = Path(__file__).resolve().parents[3]
    src, cache = repo / "examples" / "nav_base" / "interfaces", repo / ".cache" / "ros2-interfaces"

    def say(message: str) -> None:
        print(f"sim: {message}", file=sys.stderr, flush=True)

    try:
        built = ros2build.build_interfaces(
            src, cache, colcon_home=repo / ".cache" / "colcon-home", progress=say if sys.stderr.isatty() else None
        )
    except (ros2build.BuildError, RuntimeError, OSError, ImportError) as exc:
        return f"building nav_base_msgs failed: {str(exc)[:2000]}"
    use_prefix(built)
    return None


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    problem = ensure_interfaces(args.prefix)
    if problem is not None:
        print(f"sim: {problem}", file=sys.stderr)
        return 1
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    namespaces = args.namespace or ["nav_base_a"]
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    bases = [
        BaseNode(
            context,
            ns,
            core.BaseSim(ns, speed=args.speed, dock_time=args.dock_time),
            rate=args.rate,
            feedback_rate=args.feedback_rate,
        )
        for ns in namespaces
    ]
    # goals of several robots run at once, each execute callback in a thread of its own
    executor = MultiThreadedExecutor(num_threads=4 + 2 * len(bases), context=context)
    for b in bases:
        executor.add_node(b.node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    emit("ready", namespaces=namespaces, speed=args.speed)
    stop.wait(args.run_for)
    executor.shutdown(timeout_sec=5)
    spinner.join(5)
    for b in bases:
        for server in b.servers:
            server.destroy()
        b.node.destroy_node()
    rclpy.shutdown(context=context)
    return 0


if __name__ == "__main__":
    sys.exit(main())
