"""The edge node's Fast DDS defaults: what its many ROS 2 endpoints preallocate.

A fleet process holds about twenty DDS readers and writers per robot (each service client is two, each action
client five), and Fast DDS preallocates 100 samples for each: about half of what a robot costs in memory. The
profile next to this module (`fastdds.xml`) preallocates one and lets the history grow. Fast DDS reads one
profile file, named by `FASTRTPS_DEFAULT_PROFILES_FILE` (or `DEFAULT_FASTRTPS_PROFILES.xml` in the working
directory), when the process makes its first participant; a user's own profile always wins, and docs/fleet.md
shows the two elements to add to it.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping
from pathlib import Path

#: the file this module applies
PROFILE = Path(__file__).with_name("fastdds.xml")
#: the variable Fast DDS 2.x (ROS 2 Jazzy's) reads its profile file's path from
PROFILE_VARIABLE = "FASTRTPS_DEFAULT_PROFILES_FILE"
#: every variable naming a user's profile (Fast DDS 3 reads the second)
USER_VARIABLES = (PROFILE_VARIABLE, "FASTDDS_DEFAULT_PROFILES_FILE")
#: the file Fast DDS loads from the working directory when the variable is not set
WORKING_DIRECTORY_PROFILE = "DEFAULT_FASTRTPS_PROFILES.xml"
#: the RMW implementations that are Fast DDS (the first is ROS 2 Jazzy's default, also when none is named)
FAST_DDS = ("rmw_fastrtps_cpp", "rmw_fastrtps_dynamic_cpp")


def apply_edge_profile(environ: MutableMapping[str, str] | None = None, cwd: Path | None = None) -> bool:
    """Name the edge node's profile in `environ` (the process's by default) before rclpy makes a participant,
    unless the RMW is not Fast DDS or a profile of the user's is already in effect. Whether it did."""
    environ = os.environ if environ is None else environ
    if environ.get("RMW_IMPLEMENTATION", FAST_DDS[0]) not in FAST_DDS:
        return False
    if any(environ.get(name) for name in USER_VARIABLES) or ((cwd or Path.cwd()) / WORKING_DIRECTORY_PROFILE).is_file():
        return False
    environ[PROFILE_VARIABLE] = str(PROFILE)
    return True
