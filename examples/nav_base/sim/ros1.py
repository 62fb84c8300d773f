"""The simulated nav_base on ROS 1 (rospy + actionlib): `core.BaseSim` behind the same names as on ROS 2.

Run it with Debian's interpreter (where rospy and actionlib live), against a running master, with the genpy
modules of nav_base_msgs (its actions expanded as genaction does) on the path or given with --genpy:

    ROS_MASTER_URI=http://127.0.0.1:11311 /usr/bin/python3 examples/nav_base/sim/ros1.py \\
        --namespace nav_base_a --genpy DIR [--speed 1.0] [--dock-time 0.5] [--feedback-rate 10] [--rate 10]

Per robot namespace NS: real actionlib `ActionServer`s on `/NS/navigate_to_pose`, `/NS/dock_robot` and
`/NS/undock_robot` (the `goal|cancel|status|feedback|result` topics; a goal refused because the base is busy,
the pose unreachable or the motors off is rejected with the reason as its status text), the std_srvs services
`/NS/stop` (Trigger) and `/NS/enable_motors` (SetBool), `/NS/cmd_vel` (geometry_msgs/Twist) subscribed,
`/NS/odom` (nav_msgs/Odometry), `/NS/battery_state` (sensor_msgs/BatteryState) and `/NS/scan`
(sensor_msgs/LaserScan) published. One JSON object per line on stdout: `ready`, then `goal` and `result` events
as the ROS 2 simulation prints them.
"""

from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent

if __package__:
    from . import core
else:  # run as a script
    sys.path.insert(0, str(HERE))
    import core  # type: ignore[no-redef]


def emit(event: str, **fields: Any) -> None:
    sys.stdout.write(json.dumps({"event": event, **fields}, sort_keys=True) + "\n")
    sys.stdout.flush()


class Ros1Base:
    """Serves one core.BaseSim under `ns`: one thread per running goal, the topics on the caller's thread."""

    def __init__(self, base: core.BaseSim, ns: str, feedback_rate: float) -> None:
        import actionlib
        import rospy
        from geometry_msgs.msg import Twist
        from nav_base_msgs.msg import DockRobotAction, NavigateToPoseAction, UndockRobotAction
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import BatteryState, LaserScan
        from std_srvs.srv import SetBool, Trigger

        self.rospy = rospy
        self.base = base
        self.ns = ns.strip("/")
        self.period = 1.0 / feedback_rate
        self.servers = []
        for name, kind, spec in (
            ("navigate_to_pose", core.NAVIGATE, NavigateToPoseAction),
            ("dock_robot", core.DOCK, DockRobotAction),
            ("undock_robot", core.UNDOCK, UndockRobotAction),
        ):
            server = actionlib.ActionServer(
                f"/{self.ns}/{name}", spec, self._on_goal(name, kind, spec), self._on_cancel, auto_start=False
            )
            server.start()
            self.servers.append(server)
        self.running: dict[str, core.Task] = {}  # goal id → its task
        self.services = [
            rospy.Service(f"/{self.ns}/stop", Trigger, self._stop),
            rospy.Service(f"/{self.ns}/enable_motors", SetBool, self._enable),
        ]
        self.cmd: tuple[float, float, float] | None = None
        self.cmd_sub = rospy.Subscriber(f"/{self.ns}/cmd_vel", Twist, self._on_cmd, queue_size=10)
        self.odom_pub = rospy.Publisher(f"/{self.ns}/odom", Odometry, queue_size=10)
        self.battery_pub = rospy.Publisher(f"/{self.ns}/battery_state", BatteryState, queue_size=10)
        self.scan_pub = rospy.Publisher(f"/{self.ns}/scan", LaserScan, queue_size=5)

    # -- actions -------------------------------------------------------------------------------------------

    def _on_goal(self, name: str, kind: str, spec: Any) -> Any:
        result_class = type(spec().action_result.result)

        def on_goal(handle: Any) -> None:
            goal = handle.get_goal()
            try:
                task = self._start(kind, goal)
            except core.Refused as exc:
                emit("goal", robot=self.ns, action=name, accepted=False, reason=str(exc))
                handle.set_rejected(result_class(), str(exc))
                return
            handle.set_accepted("accepted")
            self.running[handle.get_goal_id().id] = task
            emit("goal", robot=self.ns, action=name, accepted=True)
            worker = threading.Thread(target=self._execute, args=(name, kind, spec, handle, task), daemon=True)
            worker.start()

        return on_goal

    def _start(self, kind: str, goal: Any) -> core.Task:
        if kind == core.NAVIGATE:
            p = goal.pose.pose
            return self.base.navigate(p.position.x, p.position.y, core.yaw_of(p.orientation.z, p.orientation.w))
        if kind == core.DOCK:
            dock_id = goal.dock_id if goal.use_dock_id else self._cart_at(goal.dock_pose.pose.position)
            return self.base.dock(dock_id)
        return self.base.undock()

    def _cart_at(self, position: Any) -> str:
        for cart, (x, y) in self.base.carts.items():
            if math.hypot(x - position.x, y - position.y) <= core.DOCK_RADIUS:
                return cart
        return ""

    def _on_cancel(self, handle: Any) -> None:
        task = self.running.get(handle.get_goal_id().id)
        if task is not None:
            task.cancel()  # the goal's thread sees it end and reports it canceled

    def _execute(self, name: str, kind: str, spec: Any, handle: Any, task: core.Task) -> None:
        feedback_class = type(spec().action_feedback.feedback)
        result = type(spec().action_result.result)()
        stop = threading.Event()
        while not task.done and not self.rospy.is_shutdown():
            feedback = self._feedback(kind, feedback_class, task)
            if feedback is not None:
                handle.publish_feedback(feedback)
            stop.wait(self.period)
        self.running.pop(handle.get_goal_id().id, None)
        failed = task.state != core.SUCCEEDED
        result.error_msg = task.message
        result.error_code = task.error_code if task.state == core.FAILED else 0
        if hasattr(result, "success"):
            result.success = not failed
        canceled = task.state == core.CANCELED and handle.get_goal_status().status in (
            handle.get_goal_status().PREEMPTING,
            handle.get_goal_status().RECALLING,
        )
        if not failed:
            handle.set_succeeded(result, task.message)
        elif canceled:
            handle.set_canceled(result, task.message)
        else:
            if not result.error_code:
                result.error_code = core.NAV_UNKNOWN if kind == core.NAVIGATE else core.DOCK_NOT_VALID
            handle.set_aborted(result, task.message)
        emit("result", robot=self.ns, action=name, state=task.state, error_code=result.error_code)

    def _feedback(self, kind: str, feedback_class: Any, task: core.Task) -> Any:
        if kind == core.UNDOCK:
            return None
        feedback = feedback_class()
        if kind == core.NAVIGATE:
            x, y, theta = task.pose()
            pose = feedback.current_pose
            pose.header.stamp = self.rospy.Time.now()
            pose.header.frame_id = "map"
            pose.pose.position.x, pose.pose.position.y = x, y
            pose.pose.orientation.z, pose.pose.orientation.w = core.quaternion_z_w(theta)
            feedback.navigation_time = self.rospy.Duration.from_sec(task.elapsed())
            feedback.estimated_time_remaining = self.rospy.Duration.from_sec(task.time_left())
            feedback.distance_remaining = task.remaining()
        else:
            feedback.state = core.DOCK_INITIAL_PERCEPTION if task.progress() < 0.5 else core.DOCK_CONTROLLING
            feedback.docking_time = self.rospy.Duration.from_sec(task.elapsed())
        return feedback

    # -- services and topics -------------------------------------------------------------------------------

    def _stop(self, _request: Any) -> Any:
        from std_srvs.srv import TriggerResponse

        success, message = self.base.stop()
        emit("call", robot=self.ns, service="stop", message=message)
        return TriggerResponse(success=success, message=message)

    def _enable(self, request: Any) -> Any:
        from std_srvs.srv import SetBoolResponse

        success, message = self.base.set_motors(bool(request.data))
        emit("call", robot=self.ns, service="enable_motors", data=bool(request.data))
        return SetBoolResponse(success=success, message=message)

    def _on_cmd(self, msg: Any) -> None:
        self.cmd = (msg.linear.x, msg.angular.z, self.base.clock())

    def publish(self, dt: float) -> None:
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import BatteryState, LaserScan

        now = self.base.clock()
        if self.cmd is not None and now - self.cmd[2] <= 0.5:
            self.base.drive(self.cmd[0], self.cmd[1], min(dt, 0.5))
        stamp = self.rospy.Time.now()
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
        battery.percentage = self.base.battery
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Simulated nav_base on ROS 1 (rospy + actionlib).")
    parser.add_argument("--namespace", action="append", help="robot namespace (repeatable; default nav_base_a)")
    parser.add_argument("--genpy", type=Path, action="append", default=[], help="directory holding nav_base_msgs")
    parser.add_argument("--speed", type=float, default=1.0, help="driving speed (m/s)")
    parser.add_argument("--dock-time", type=float, default=0.5, help="seconds a docking takes")
    parser.add_argument("--feedback-rate", type=float, default=10.0, help="action feedback messages per second")
    parser.add_argument("--rate", type=float, default=10.0, help="odom/battery/scan publishing rate (Hz)")
    parser.add_argument("--run-for", type=float, default=None, help="exit after this many seconds")
    args = parser.parse_args(argv)
    for directory in reversed(args.genpy):
        sys.path.insert(0, str(directory))
    import rospy

    namespaces = args.namespace or ["nav_base_a"]
    rospy.init_node("nav_base_sim", anonymous=True, disable_signals=True)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    bases = [
        Ros1Base(core.BaseSim(ns, speed=args.speed, dock_time=args.dock_time), ns, args.feedback_rate)
        for ns in namespaces
    ]
    emit("ready", namespaces=namespaces, speed=args.speed)
    period = 1.0 / args.rate
    deadline = None if args.run_for is None else time.monotonic() + args.run_for
    try:
        while not stop.is_set() and not rospy.is_shutdown():
            if deadline is not None and time.monotonic() >= deadline:
                break
            for b in bases:
                b.publish(period)
            stop.wait(period)
    finally:
        rospy.signal_shutdown("simulation stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
