#!/usr/bin/env bash
# ROS 1 (Noetic-era rospy, actionlib) from Debian 12 packages, for the rospy backend's real-runtime tests
# (python3-move-base-msgs: genaction output built by Debian, to check td2adaptor's ROS 1 action md5 sums).
# Called by .ci/setup.sh --test with $SUDO set ("" as root, "sudo" otherwise). Idempotent and quiet.
# Uses Debian's /usr/bin/python3 (the packages live in /usr/lib/python3/dist-packages).
set -euo pipefail

SUDO="${SUDO-}"
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks
PACKAGES=(
  python3-rospy python3-rosmaster python3-std-srvs python3-std-msgs
  python3-genpy python3-genmsg python3-catkin-pkg
  ros-std-msgs ros-geometry-msgs python3-geometry-msgs
  catkin rosbash rospack-tools python3-roslaunch
  python3-actionlib python3-actionlib-msgs python3-move-base-msgs
)

if ! command -v apt-get >/dev/null; then
  echo "setup-ros1: no apt-get; install these Debian packages yourself: ${PACKAGES[*]}" >&2
  exit 1
fi

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

if [ "${#missing[@]}" -gt 0 ]; then
  log="$(mktemp)"
  trap 'rm -f "$log"' EXIT
  if ! { apt_install "${missing[@]}"; } >"$log" 2>&1; then
    cat "$log" >&2
    echo "setup-ros1: could not install ${missing[*]}" >&2
    exit 1
  fi
fi

/usr/bin/python3 -c "import rospy, rosmaster, genpy, genmsg, catkin_pkg, std_msgs.msg, std_srvs.srv, geometry_msgs.msg, actionlib, actionlib_msgs.msg, move_base_msgs.msg" \
  || { echo "setup-ros1: Debian's rospy is not importable by /usr/bin/python3" >&2; exit 1; }
for tool in rosmaster catkin_make rosrun roslaunch; do
  command -v "$tool" >/dev/null || { echo "setup-ros1: $tool is not on PATH" >&2; exit 1; }
done
