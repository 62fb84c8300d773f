"""Nav2's own NavigateToPose action as published (tests/data/nav2: builtin_interfaces/Duration in its feedback, a
ROS 2 only type) through the whole ROS 2 path, on real ROS 2 Jazzy: the TD is valid for ROS 2, `gen` makes the
rclpy adaptor, nav2_msgs is built with the project's interface build (td2adaptor.support.ros2build), and the
adaptor sends a goal to a real rclpy ActionServer, follows its feedback (the Durations included) and reads the
result. The server and the adaptor run in a child process that loads the built prefix (nothing of it is loaded
into this process)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import td2adaptor
from td2adaptor.backends.registry import load as load_backend
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from td2adaptor.support import ros2build
from tests.lowering.test_distros import NAV2, nav2_td
from tests.ros2 import env
from tests.ros2.build import CACHE, COLCON_HOME

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain

ROBOT = "nav2_base_a"

_SCENARIO = """
import json, sys, threading, time
import rclpy
from rclpy.action import ActionServer
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from nav2_msgs.action import NavigateToPose
from nav2_base_adaptor import NavigationComponent, spin_in_background

context = Context()
rclpy.init(context=context)
server_node = rclpy.create_node("nav2_server", context=context)

def execute(handle):
    for step in range(3):
        feedback = NavigateToPose.Feedback()
        feedback.current_pose = handle.request.pose
        feedback.navigation_time.sec, feedback.navigation_time.nanosec = step, 250_000_000 * step
        feedback.estimated_time_remaining.sec = 3 - step
        feedback.distance_remaining = 1.5 - 0.5 * step
        handle.publish_feedback(feedback)
        time.sleep(0.05)
    handle.succeed()
    result = NavigateToPose.Result()
    result.error_code = result.NONE
    result.error_msg = "there: " + handle.request.behavior_tree
    return result

server = ActionServer(
    server_node, NavigateToPose, "/ROBOT/navigate_to_pose", execute_callback=execute,
    callback_group=ReentrantCallbackGroup(),
)
executor = MultiThreadedExecutor(num_threads=2, context=context)
executor.add_node(server_node)
serving = threading.Thread(target=executor.spin, daemon=True)
serving.start()

client_node = rclpy.create_node("nav2_client", context=context)
spinner = spin_in_background(client_node)
nav = NavigationComponent(client_node, "ROBOT", timeout=20.0, wait_timeout=20.0)
pose = {"header": {"frame_id": "map"}, "pose": {"position": {"x": 2.0, "y": 1.0}, "orientation": {"w": 1.0}}}
goal = nav.send_navigateToPose(nav.construct_navigateToPose_Goal(pose=pose, behavior_tree="bt.xml"))
feedback = [
    [f.navigation_time.sec, f.navigation_time.nanosec, f.estimated_time_remaining.sec, f.distance_remaining,
     f.current_pose.header.frame_id]
    for f in goal.feedback(timeout=20.0)
]
result = goal.result(timeout=20.0)
print(json.dumps({"feedback": feedback, "error_code": result.error_code, "error_msg": result.error_msg,
                  "status": goal.status}), flush=True)
spinner.stop()
executor.shutdown(timeout_sec=5)
serving.join(10)  # a spin thread still running when the interpreter exits aborts it ("terminate called ...")
client_node.destroy_node()
server_node.destroy_node()
rclpy.shutdown(context=context)
""".replace("ROBOT", ROBOT)


def test_nav2_navigate_to_pose_end_to_end_on_ros2(ros2_domain: int, tmp_path: Path) -> None:
    td = tmp_path / "td.json"
    td.write_text(json.dumps(nav2_td()), encoding="utf-8")
    result = td2adaptor.compile(td, interfaces=[NAV2])
    assert result.model is not None, [d.message for d in result.diagnostics]
    diags = Diagnostics()
    tree = load_backend("rclpy").generate(result.model, GenOptions(), diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    for rel, data in tree:
        path = tmp_path / "src" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    prefix = ros2build.build_interfaces(NAV2, CACHE, colcon_home=COLCON_HOME)
    child = env.child_env([prefix], [tmp_path / "src" / result.model.package_name])
    run = subprocess.run(
        [sys.executable, "-c", _SCENARIO], env=child, capture_output=True, text=True, timeout=240, cwd=tmp_path
    )
    assert run.returncode == 0, run.stdout + run.stderr
    outcome = json.loads(run.stdout.strip().splitlines()[-1])
    assert outcome["feedback"] == [
        [0, 0, 3, 1.5, "map"],
        [1, 250_000_000, 2, 1.0, "map"],
        [2, 500_000_000, 1, 0.5, "map"],
    ]
    assert (outcome["error_code"], outcome["error_msg"], outcome["status"]) == (0, "there: bt.xml", "succeeded")
