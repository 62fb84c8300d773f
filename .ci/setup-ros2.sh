#!/usr/bin/env bash
# ROS 2 Jazzy from PyPI wheels (pip extra `ros2`), for the rclpy backend's real-runtime tests.
# Called by .ci/setup.sh --test with $SUDO set ("" as root, "sudo" otherwise). Idempotent and quiet.
#   host tools: cmake, ninja, gcc/g++ (the tests build the RB-1 interfaces with CMake) and the headers of the
#               venv's Python (the rosidl Python typesupport is a C extension).
#   .venv:      ros-jazzy-rclpy[fastrtps]==7.1.6, message packages, rosidl/ament build extras, colcon.
set -euo pipefail
cd "$(dirname "$0")/.."
SUDO="${SUDO-}"
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks

if [ ! -x .venv/bin/python ]; then
  echo "setup-ros2: run .ci/setup.sh first (no .venv)" >&2
  exit 1
fi
if [ "$(uname -m)" != x86_64 ]; then
  echo "setup-ros2: the ROS 2 Jazzy wheels exist for x86_64 Linux only (this is $(uname -m))" >&2
  exit 1
fi

want=(cmake ninja-build gcc g++ make)
# The venv's interpreter needs its C headers; Debian's python3 has them in python3-dev.
if ! .venv/bin/python -c 'import os, sysconfig, sys; sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  want+=(python3-dev)
fi
missing=()
for pkg in "${want[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then missing+=("$pkg"); fi
done
if [ "${#missing[@]}" -gt 0 ]; then
  if ! command -v apt-get >/dev/null; then
    echo "setup-ros2: please install these packages yourself: ${missing[*]}" >&2; exit 1
  fi
  apt_install "${missing[@]}" >/dev/null
fi

# Quiet, but show pip's output when it fails.
log="$(mktemp)"
if ! .venv/bin/python -m pip install -q -e '.[test,ros2]' >"$log" 2>&1; then
  cat "$log" >&2; rm -f "$log"
  echo "setup-ros2: pip install of the ros2 extra failed" >&2
  exit 1
fi
rm -f "$log"

for tool in cmake ninja g++ .venv/bin/colcon; do
  command -v "$tool" >/dev/null || { echo "setup-ros2: $tool not found after installation" >&2; exit 1; }
done
# rclpy loads through the wheels' bootstrapper (.pth + re-exec); check that it imports and finds its RMW.
.venv/bin/python -c "import rclpy, std_msgs.msg, std_srvs.srv, geometry_msgs.msg, rosidl_adapter, catkin_pkg" \
  || { echo "setup-ros2: rclpy or the message packages do not import from .venv" >&2; exit 1; }
