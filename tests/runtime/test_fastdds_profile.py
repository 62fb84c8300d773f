"""The edge node's Fast DDS defaults (td2adaptor/runtime/ros/fastdds.py): applied only when the user has no
profile of their own and the RMW is Fast DDS, and a file the real Fast DDS of the ROS 2 wheels reads without
complaint (its memory effect is measured by bench/fleet_ros2.py, "RSS per robot added to one process")."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from td2adaptor.runtime.ros.fastdds import PROFILE, PROFILE_VARIABLE, WORKING_DIRECTORY_PROFILE, apply_edge_profile
from tests.ros2 import env

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain (a private domain, Fast DDS)


def test_the_profile_is_named_only_when_no_profile_of_the_users_is_in_effect(tmp_path: Path) -> None:
    environ: dict[str, str] = {}
    assert apply_edge_profile(environ, tmp_path) and environ == {PROFILE_VARIABLE: str(PROFILE)}
    environ = {"RMW_IMPLEMENTATION": "rmw_fastrtps_dynamic_cpp"}
    assert apply_edge_profile(environ, tmp_path) and environ[PROFILE_VARIABLE] == str(PROFILE)
    mine = {PROFILE_VARIABLE: "/etc/robot/fastdds.xml"}
    assert not apply_edge_profile(mine, tmp_path) and mine == {PROFILE_VARIABLE: "/etc/robot/fastdds.xml"}
    fast_dds_3 = {"FASTDDS_DEFAULT_PROFILES_FILE": "/etc/robot/fastdds.xml"}
    assert not apply_edge_profile(fast_dds_3, tmp_path) and PROFILE_VARIABLE not in fast_dds_3
    cyclone = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    assert not apply_edge_profile(cyclone, tmp_path) and PROFILE_VARIABLE not in cyclone
    (tmp_path / WORKING_DIRECTORY_PROFILE).write_text("<profiles/>", encoding="utf-8")
    environ = {}
    assert not apply_edge_profile(environ, tmp_path) and environ == {}


NODE = """
import rclpy
from rclpy.node import Node
from test_msgs.srv import Empty
from test_msgs.msg import Strings
rclpy.init()
node = Node("profile_check")
node.create_client(Empty, "profile_check/service")
node.create_subscription(Strings, "profile_check/topic", lambda message: None, 10)
node.create_publisher(Strings, "profile_check/topic", 10)
node.destroy_node()
rclpy.shutdown()
print("made")
"""


def parse_errors(profile: Path) -> str:
    """What Fast DDS says about `profile` while a process makes a participant, a reader and writers."""
    environ = env.child_env([])
    environ[PROFILE_VARIABLE] = str(profile)
    done = subprocess.run([sys.executable, "-c", NODE], env=environ, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "made" in done.stdout, done.stderr
    return "\n".join(line for line in (done.stdout + done.stderr).splitlines() if "XMLPARSER" in line)


def test_fast_dds_reads_the_profile_without_an_error(ros2_domain: int, tmp_path: Path) -> None:
    assert parse_errors(PROFILE) == ""
    # the check can fail: a misspelt element is reported
    broken = tmp_path / "broken.xml"
    broken.write_text(PROFILE.read_text(encoding="utf-8").replace("allocated_samples>", "allocated_sample>"))
    assert "Error parsing" in parse_errors(broken)


def test_docs_show_the_profiles_defaults_as_the_file_has_them() -> None:
    """docs/fleet.md tells a user with a profile of their own what to add: the same elements as the file."""
    import re
    import xml.etree.ElementTree as ET

    from tests.conftest import REPO

    page = (REPO / "docs" / "fleet.md").read_text(encoding="utf-8")
    found = re.search(r"<!-- edge-endpoint-profile -->\n\s*```xml\n(.*?)```", page, re.S)
    assert found, "docs/fleet.md lost the edge node's endpoint defaults"
    shown = ET.fromstring(f"<profiles>{found.group(1)}</profiles>")
    shipped = ET.parse(PROFILE).getroot()

    def canonical(root: ET.Element) -> list[str]:
        out = []
        for element in root:
            element.tag = element.tag.split("}")[-1]
            for inner in element.iter():
                inner.tag = inner.tag.split("}")[-1]
                inner.text = (inner.text or "").strip() or None
                inner.tail = None
            out.append(ET.tostring(element, encoding="unicode"))
        return out

    assert canonical(shown) == canonical(shipped)
