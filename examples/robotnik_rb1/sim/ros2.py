"""The simulated RB-1 on ROS 2 (rclpy): `core.RobotSim` served on the robot's real services and topics.

One command starts it (one node per robot, all in this process):

    .venv/bin/python -m examples.robotnik_rb1.sim.ros2 --namespace rb1_base_a --duration 1.0

    --namespace NS   a robot namespace; repeat it for several robots (rb1_base_a, rb1_base_b, rb1_base_c)
    --count N        a fleet: N robots NS_0 ... NS_<N-1> (NS: the one --namespace, default rb1_base), e.g.
                     `--count 100` serves rb1_base_0 ... rb1_base_99 in this one process
    --quiet          no `call` lines (a fleet's hundreds of calls per second)
    --executor KIND  `single` (rclpy's SingleThreadedExecutor, the default) or `events` (rclpy's experimental
                     EventsExecutor, in C++: a Python executor rebuilds its wait set of every service, timer
                     and subscription at each wake-up, which for 100 robots costs a core at idle)
    --duration S     how long a procedure runs (default 1.0); --queue-time S before it starts (default 0.05)
    --rate HZ        how often Status and AlvarMarkers are published (default 10)
    --run-for S      exit after S seconds (default: until SIGINT/SIGTERM)
    --prefix DIR     an install prefix holding the RB-1 interfaces (repeatable); without one, and when they
                     are not importable already, they are built once with CMake into .cache/ros2-interfaces

Per robot NS it serves `/NS/robot_local_control/NavigationComponent/{GoTo,Pick,Place}Component/{add,cancel,
query_state}` with the robot's semantics (`core.py`), publishes `/NS/robot_local_control/state`
(robot_local_control_msgs/Status; operation_state follows the procedures) and `/NS/ar_pose_marker`
(ar_track_alvar_msgs/AlvarMarkers: the markers the robot sees where it stands), and subscribes to the door
command `/door1/door_controller/command` (std_msgs/Float64, transient local, so a latched command arrives).
It prints one JSON object per line on stdout: `{"event": "ready", ...}` once everything is up, then
`{"event": "door", "value": ...}` for each door command and `{"event": "call", ...}` for each service call
(unless --quiet).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import Any, cast

from examples.robotnik_rb1.sim.core import RobotSim

COMPONENTS = ("GoToComponent", "PickComponent", "PlaceComponent")
DOOR_TOPIC = "/door1/door_controller/command"


def emit(event: str, **fields: Any) -> None:
    """One event line on stdout (tests and demos read these)."""
    print(json.dumps({"event": event, **fields}, sort_keys=True), flush=True)


def use_prefix(prefix: Path) -> None:
    """Import interfaces from an install prefix: its site-packages on sys.path, its libraries preloaded.

    rosidl loads the typesupport libraries by bare name, which only LD_LIBRARY_PATH at start-up (or a library
    already loaded) satisfies; preloading with RTLD_GLOBAL spares the caller setting the environment.
    """
    py = f"python{sys.version_info.major}.{sys.version_info.minor}"
    sys.path.insert(0, str(prefix / "lib" / py / "site-packages"))
    pending = sorted((prefix / "lib").glob("lib*.so"))
    while pending:
        failed = []
        for lib in pending:
            try:
                ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            except OSError:
                failed.append(lib)
        if len(failed) == len(pending):
            raise OSError(f"cannot load {failed}")
        pending = failed


class RobotNode:
    """One simulated robot: a node in namespace `ns` serving core.RobotSim."""

    def __init__(self, context: Any, ns: str, robot: RobotSim, rate: float, *, quiet: bool = False) -> None:
        import rclpy
        from ar_track_alvar_msgs.msg import AlvarMarkers
        from procedures_msgs.srv import ProcedureQuery
        from robot_local_control_msgs.msg import Status
        from robot_local_control_msgs.srv import GoToPetition, PickPetition, PlacePetition

        self.ns = ns
        self.robot = robot
        self.quiet = quiet
        self.node: Any = rclpy.create_node("rb1_sim", namespace="/" + ns, context=context)
        petitions = {"GoToComponent": GoToPetition, "PickComponent": PickPetition, "PlaceComponent": PlacePetition}
        base = f"/{ns}/robot_local_control/NavigationComponent"
        for comp in COMPONENTS:
            self.node.create_service(petitions[comp], f"{base}/{comp}/add", self._add(comp))
            self.node.create_service(ProcedureQuery, f"{base}/{comp}/cancel", self._query(comp, cancel=True))
            self.node.create_service(ProcedureQuery, f"{base}/{comp}/query_state", self._query(comp, cancel=False))
        self.status_pub = self.node.create_publisher(Status, f"/{ns}/robot_local_control/state", 10)
        self.marker_pub = self.node.create_publisher(AlvarMarkers, f"/{ns}/ar_pose_marker", 10)
        self.node.create_timer(1.0 / rate, self.publish)

    @staticmethod
    def _fill(response: Any, reply: dict[str, Any], stamp: Any) -> None:
        state, result = reply["state"], reply["result"]
        response.state.header.id = int(state["header"]["id"])
        response.state.header.priority = int(state["header"]["priority"])
        response.state.header.name = str(state["header"]["name"])
        response.state.header.stamp = stamp
        response.state.current_state = state["current_state"]
        response.state.last_event = state["last_event"]
        response.result.result = result["result"]
        response.result.message = result["message"]
        if hasattr(response, "last_message"):
            response.last_message.data = reply.get("last_message", "")

    def _add(self, comp: str) -> Callable[[Any, Any], Any]:
        def serve(request: Any, response: Any) -> Any:
            procedure = request.procedure
            if comp == "GoToComponent":
                params: dict[str, Any] = {
                    "goals": [{"pose": {"x": g.pose.x, "y": g.pose.y, "theta": g.pose.theta}} for g in procedure.goals]
                }
            else:
                params = {"pick_frame_id": procedure.pick_frame_id}
            reply = self.robot.components[comp].add(params)
            self._fill(response, reply, self.node.get_clock().now().to_msg())
            if self.quiet:
                return response
            emit(
                "call",
                robot=self.ns,
                component=comp,
                op="add",
                id=response.state.header.id,
                result=response.result.result,
            )
            return response

        return serve

    def _query(self, comp: str, *, cancel: bool) -> Callable[[Any, Any], Any]:
        def serve(request: Any, response: Any) -> Any:
            component = self.robot.components[comp]
            mission = int(request.header.id)
            reply = component.cancel(mission) if cancel else component.query(mission)
            self._fill(response, reply, self.node.get_clock().now().to_msg())
            if self.quiet:
                return response
            emit(
                "call",
                robot=self.ns,
                component=comp,
                op="cancel" if cancel else "query_state",
                id=mission,
                state=response.state.current_state,
                result=response.result.result,
            )
            return response

        return serve

    def publish(self) -> None:
        from ar_track_alvar_msgs.msg import AlvarMarker, AlvarMarkers
        from robot_local_control_msgs.msg import Status

        stamp = self.node.get_clock().now().to_msg()
        info = self.robot.status()
        status = Status(
            robot_id=info["robot_id"],
            robot_state=info["robot_state"],
            control_state=info["control_state"],
            operation_state=info["operation_state"],
        )
        current = info["mission_status"]["current"]
        status.mission_status.current.id = int(current["id"])
        status.mission_status.current.description = current["description"]
        status.mission_status.current.state = current["state"]
        x, y, theta = info["pose"]
        for pose in (status.robot_status.pose, status.localization_status.pose):
            pose.header.stamp = stamp
            pose.header.frame_id = "map"
            pose.pose.x, pose.pose.y, pose.pose.theta = float(x), float(y), float(theta)
        status.localization_status.reliable = True
        status.localization_status.state = "ready"
        status.navigation_status.state = "ready"
        status.robot_status.battery.level = 87.0
        status.robot_status.elevator.position = "up" if info["carrying"] else "down"
        self.status_pub.publish(status)

        markers = AlvarMarkers()
        markers.header.stamp = stamp
        markers.header.frame_id = f"{self.ns}_front_camera"
        for marker_id in self.robot.visible_markers():
            marker = AlvarMarker(id=marker_id, confidence=100)
            marker.header = markers.header
            marker.pose.header = markers.header
            marker.pose.pose.position.x = 0.4
            marker.pose.pose.orientation.w = 1.0
            markers.markers.append(marker)
        self.marker_pub.publish(markers)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m examples.robotnik_rb1.sim.ros2", description=__doc__.split("\n")[0]
    )
    parser.add_argument("--namespace", action="append", help="robot namespace (repeatable; default rb1_base_a)")
    parser.add_argument("--count", type=int, default=None, help="a fleet of N robots: NS_0 ... NS_<N-1>")
    parser.add_argument("--quiet", action="store_true", help="no `call` event lines")
    parser.add_argument("--executor", choices=("single", "events"), default="single", help="rclpy executor")
    parser.add_argument("--duration", type=float, default=1.0, help="seconds a procedure runs")
    parser.add_argument("--queue-time", type=float, default=0.05, help="seconds before a procedure starts")
    parser.add_argument("--rate", type=float, default=10.0, help="Status/AlvarMarkers publishing rate (Hz)")
    parser.add_argument("--run-for", type=float, default=None, help="exit after this many seconds")
    parser.add_argument("--prefix", action="append", default=[], help="install prefix of the RB-1 interfaces")
    return parser.parse_args(argv)


def namespaces(args: argparse.Namespace) -> list[str]:
    """The robots to serve: the --namespace values, or with --count N the fleet NS_0 ... NS_<N-1>."""
    if args.count is None:
        return list(args.namespace or ["rb1_base_a"])
    if args.count < 1:
        raise SystemExit("--count must be at least 1")
    if args.namespace and len(args.namespace) > 1:
        raise SystemExit("--count takes one --namespace (the fleet's prefix)")
    prefix = args.namespace[0] if args.namespace else "rb1_base"
    return [f"{prefix}_{i}" for i in range(args.count)]


def ensure_interfaces(prefixes: Sequence[str]) -> str | None:
    """Make the RB-1 interfaces importable: the given prefixes, or else the source checkout's build of them
    (made with CMake on first use and cached in .cache/ros2-interfaces, as the warehouse demo does). The
    reason when that cannot be done, for one line on stderr."""
    import importlib.util

    if importlib.util.find_spec("rclpy") is None:
        return "ROS 2 Jazzy (rclpy) is not installed: bash .ci/setup-ros2.sh, or pip install -e '.[ros2]'"
    for prefix in prefixes:
        use_prefix(Path(prefix))
    if prefixes or importlib.util.find_spec("ar_track_alvar_msgs") is not None:
        return None
    from td2adaptor.support import ros2build

    repo = Path(__file__).resolve().parents[3]
    src, cache = repo / "examples" / "robotnik_rb1" / "interfaces", repo / ".cache" / "ros2-interfaces"

    def say(message: str) -> None:
        print(f"sim: {message}", file=sys.stderr, flush=True)

    try:
        prefix = ros2build.build_interfaces(
            src, cache, colcon_home=repo / ".cache" / "colcon-home", progress=say if sys.stderr.isatty() else None
        )
    except (ros2build.BuildError, RuntimeError, OSError, ImportError) as exc:
        return f"building the RB-1 interfaces failed: {str(exc)[:2000]}"
    use_prefix(prefix)
    return None


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    names = namespaces(args)
    problem = ensure_interfaces(args.prefix)
    if problem is not None:
        print(f"sim: {problem}", file=sys.stderr)
        return 1
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions
    from std_msgs.msg import Float64

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)

    robots = [
        RobotNode(
            context, ns, RobotSim(ns, duration=args.duration, queue_time=args.queue_time), args.rate, quiet=args.quiet
        )
        for ns in names
    ]

    def on_door(msg: Float64) -> None:
        for r in robots:
            r.robot.set_door(msg.data)
        emit("door", value=msg.data)

    door_qos = cast(Any, QoSProfile)(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    )
    robots[0].node.create_subscription(Float64, DOOR_TOPIC, on_door, door_qos)
    executor: Any
    if args.executor == "events":
        from rclpy.experimental import EventsExecutor

        executor = EventsExecutor(context=context)
    else:
        executor = SingleThreadedExecutor(context=context)
    for r in robots:
        executor.add_node(r.node)
    emit("ready", namespaces=names, duration=args.duration)
    deadline = None if args.run_for is None else time.monotonic() + args.run_for
    try:
        while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        for r in robots:
            r.node.destroy_node()
        rclpy.shutdown(context=context)
    return 0


if __name__ == "__main__":
    sys.exit(main())
