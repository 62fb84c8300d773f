"""The simulated RB-1 on ROS 1 (rospy): `core.RobotSim` behind the robot's real service and topic names.

Run it with Debian's interpreter (where rospy lives), against a running master:

    ROS_MASTER_URI=http://127.0.0.1:11311 /usr/bin/python3 examples/robotnik_rb1/sim/ros1.py \\
        --namespace rb1_base_a --duration 1.0

It serves the nine procedure services under /<namespace>/robot_local_control/NavigationComponent/
{GoTo,Pick,Place}Component/{add,cancel,query_state}, publishes /<namespace>/robot_local_control/state
(robot_local_control_msgs/Status) and /<namespace>/ar_pose_marker (ar_track_alvar_msgs/AlvarMarkers), and
subscribes to /door1/door_controller/command (std_msgs/Float64). It prints `ready` once everything is
advertised and `door <value>` for every door command, one line each, flushed.

The RB-1's custom types are generated with genpy from examples/robotnik_rb1/interfaces into
.cache/ros1-interfaces/<hash of the definitions>/ (built once, under a file lock, so parallel test workers
share it). `--print-interfaces` only builds them and prints that directory (to put on PYTHONPATH).
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import os
import shutil
import signal
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
INTERFACES = HERE.parent / "interfaces"
CACHE = REPO / ".cache" / "ros1-interfaces"
SYSTEM_MSG_DIRS = Path("/usr/share")  # Debian's ros-*-msgs packages keep .msg sources in /usr/share/<pkg>/msg

if __package__:
    from .core import RobotSim
else:  # run as a script
    sys.path.insert(0, str(HERE))
    from core import RobotSim  # type: ignore[no-redef]


# ---------------------------------------------------------------------------------------------------------
# genpy modules of the custom interfaces, cached by content


def interfaces_digest(root: Path = INTERFACES) -> str:
    """A hash of every .msg/.srv definition under `root` (names and contents) and the generator's version."""
    h = hashlib.sha256()
    try:
        import genpy

        h.update(str(getattr(genpy, "__version__", "")).encode())
    except ImportError:  # only the digest is wanted
        pass
    for path in sorted(p for p in root.rglob("*") if p.suffix in (".msg", ".srv")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _generate(root: Path, out: Path) -> None:
    """Run genpy for every package under `root` into `out/<pkg>/{msg,srv}`."""
    from genpy.generate_initpy import write_modules
    from genpy.generator import MsgGenerator, SrvGenerator

    packages = sorted(p for p in root.iterdir() if (p / "msg").is_dir() or (p / "srv").is_dir())
    search: dict[str, list[str]] = {}
    if SYSTEM_MSG_DIRS.is_dir():
        for msg_dir in sorted(SYSTEM_MSG_DIRS.glob("*/msg")):
            search.setdefault(msg_dir.parent.name, []).append(str(msg_dir))
    for pkg in packages:
        if (pkg / "msg").is_dir():
            search[pkg.name] = [str(pkg / "msg")]
    for pkg in packages:
        (out / pkg.name).mkdir(parents=True)
        (out / pkg.name / "__init__.py").write_text("")
        for kind, generator in (("msg", MsgGenerator()), ("srv", SrvGenerator())):
            files = sorted(str(f) for f in (pkg / kind).glob(f"*.{kind}")) if (pkg / kind).is_dir() else []
            if not files:
                continue
            target = out / pkg.name / kind
            if generator.generate_messages(pkg.name, files, str(target), search) != 0:
                raise RuntimeError(f"genpy failed for {pkg.name}/{kind}")
            write_modules(str(target))


def build_interfaces(root: Path = INTERFACES, cache: Path = CACHE) -> Path:
    """The directory holding the genpy modules of `root`'s packages (put it on sys.path / PYTHONPATH)."""
    digest = interfaces_digest(root)
    final = cache / digest
    if (final / ".complete").is_file():
        return final
    cache.mkdir(parents=True, exist_ok=True)
    with open(cache / f"{digest}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (final / ".complete").is_file():
            return final
        if final.exists():
            shutil.rmtree(final)
        tmp = Path(tempfile.mkdtemp(prefix=f"{digest}.", dir=cache))
        try:
            _generate(root, tmp)
            (tmp / ".complete").write_text(digest + "\n")
            os.rename(tmp, final)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp)
    return final


# ---------------------------------------------------------------------------------------------------------
# the ROS 1 node


def _say(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


class Ros1Robot:
    """Serves one RobotSim under `namespace`."""

    def __init__(self, robot: RobotSim, namespace: str, rate: float) -> None:
        import rospy
        from ar_track_alvar_msgs.msg import AlvarMarkers
        from procedures_msgs.srv import ProcedureQuery
        from robot_local_control_msgs.msg import Status
        from robot_local_control_msgs.srv import GoToPetition, PickPetition, PlacePetition
        from std_msgs.msg import Float64

        self.rospy = rospy
        self.robot = robot
        self.ns = namespace.strip("/")
        self.rate = rate
        base = f"/{self.ns}/robot_local_control/NavigationComponent"
        self.services = []
        for comp, petition in (
            ("GoToComponent", GoToPetition),
            ("PickComponent", PickPetition),
            ("PlaceComponent", PlacePetition),
        ):
            component = robot.components[comp]
            self.services += [
                rospy.Service(f"{base}/{comp}/add", petition, self._adder(component, comp)),
                rospy.Service(f"{base}/{comp}/cancel", ProcedureQuery, self._querier(component.cancel)),
                rospy.Service(f"{base}/{comp}/query_state", ProcedureQuery, self._querier(component.query)),
            ]
        self.status_pub = rospy.Publisher(f"/{self.ns}/robot_local_control/state", Status, queue_size=10)
        self.marker_pub = rospy.Publisher(f"/{self.ns}/ar_pose_marker", AlvarMarkers, queue_size=10)
        self.door_sub = rospy.Subscriber("/door1/door_controller/command", Float64, self._door, queue_size=10)

    # -- services

    def _adder(self, component: Any, name: str) -> Any:
        from robot_local_control_msgs.srv import GoToPetitionResponse, PickPetitionResponse, PlacePetitionResponse

        response_class = {
            "GoToComponent": GoToPetitionResponse,
            "PickComponent": PickPetitionResponse,
            "PlaceComponent": PlacePetitionResponse,
        }[name]

        def handle(request: Any) -> Any:
            procedure = request.procedure
            if name == "GoToComponent":
                params: dict[str, Any] = {
                    "goals": [{"pose": {"x": g.pose.x, "y": g.pose.y, "theta": g.pose.theta}} for g in procedure.goals]
                }
            else:
                params = {"pick_frame_id": procedure.pick_frame_id}
            reply = component.add(params)
            return response_class(state=self._state(reply), result=self._result(reply))

        return handle

    def _querier(self, operation: Any) -> Any:
        from procedures_msgs.srv import ProcedureQueryResponse
        from std_msgs.msg import String

        def handle(request: Any) -> Any:
            reply = operation(int(request.header.id))
            return ProcedureQueryResponse(
                state=self._state(reply),
                result=self._result(reply),
                last_message=String(data=str(reply.get("last_message", ""))),
            )

        return handle

    def _state(self, reply: dict[str, Any]) -> Any:
        from procedures_msgs.msg import ProcedureHeader, ProcedureState

        header = reply["state"]["header"]
        return ProcedureState(
            header=ProcedureHeader(
                id=int(header["id"]), priority=int(header["priority"]), stamp=self.rospy.Time.now(), name=header["name"]
            ),
            current_state=reply["state"]["current_state"],
            last_event=reply["state"]["last_event"],
        )

    @staticmethod
    def _result(reply: dict[str, Any]) -> Any:
        from procedures_msgs.msg import ProcedureResult

        return ProcedureResult(result=reply["result"]["result"], message=reply["result"]["message"])

    # -- topics

    def _door(self, msg: Any) -> None:
        self.robot.set_door(float(msg.data))
        _say(f"door {msg.data}")

    def _status(self) -> Any:
        from robot_local_control_msgs.msg import Missions, MissionStatus, Status

        s = self.robot.status()
        msg = Status(
            robot_id=s["robot_id"],
            robot_state=s["robot_state"],
            control_state=s["control_state"],
            operation_state=s["operation_state"],
            mission_status=Missions(current=MissionStatus(**s["mission_status"]["current"])),
        )
        x, y, theta = s["pose"]
        for pose in (msg.localization_status.pose, msg.robot_status.pose):
            pose.header.stamp = self.rospy.Time.now()
            pose.header.frame_id = "map"
            pose.pose.x, pose.pose.y, pose.pose.theta = x, y, theta
        msg.localization_status.reliable = True
        msg.localization_status.state = "ready"
        msg.navigation_status.state = "ready"
        msg.robot_status.elevator.state = "idle"
        msg.robot_status.elevator.position = "up" if s["carrying"] else "down"
        return msg

    def _markers(self) -> Any:
        from ar_track_alvar_msgs.msg import AlvarMarker, AlvarMarkers

        now = self.rospy.Time.now()
        out = AlvarMarkers()
        out.header.stamp = now
        out.header.frame_id = f"{self.ns}_camera"
        for mid in self.robot.visible_markers():
            marker = AlvarMarker(id=mid, confidence=100)
            marker.header.stamp = now
            marker.header.frame_id = out.header.frame_id
            marker.pose.header = marker.header
            mx, my = self.robot.markers[mid]
            marker.pose.pose.position.x, marker.pose.pose.position.y = mx - self.robot.x, my - self.robot.y
            marker.pose.pose.orientation.w = 1.0
            out.markers.append(marker)
        return out

    def spin(self, stop: threading.Event) -> None:
        period = 1.0 / self.rate
        while not stop.is_set() and not self.rospy.is_shutdown():
            self.status_pub.publish(self._status())
            self.marker_pub.publish(self._markers())
            stop.wait(period)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Simulated Robotnik RB-1 on ROS 1 (rospy).")
    parser.add_argument("--namespace", default="rb1_base_a", help="robot namespace (default: rb1_base_a)")
    parser.add_argument("--duration", type=float, default=1.0, help="seconds a procedure runs (default: 1.0)")
    parser.add_argument("--queue-time", type=float, default=0.05, help="seconds a procedure stays queued")
    parser.add_argument("--rate", type=float, default=10.0, help="Status/AlvarMarkers publishing rate in Hz")
    parser.add_argument("--interfaces", type=Path, default=INTERFACES, help="custom interface packages")
    parser.add_argument("--cache", type=Path, default=CACHE, help="where generated genpy modules are kept")
    parser.add_argument("--print-interfaces", action="store_true", help="build the genpy modules, print their dir")
    args = parser.parse_args(argv)

    generated = build_interfaces(args.interfaces, args.cache)
    if args.print_interfaces:
        _say(str(generated))
        return 0
    sys.path.insert(0, str(generated))
    import rospy

    rospy.init_node(f"rb1_sim_{args.namespace.strip('/').replace('/', '_') or 'root'}", disable_signals=True)
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    node = Ros1Robot(
        RobotSim(args.namespace, duration=args.duration, queue_time=args.queue_time), args.namespace, args.rate
    )
    _say("ready")
    try:
        node.spin(stop)
    finally:
        rospy.signal_shutdown("simulation stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
