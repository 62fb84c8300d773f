#!/usr/bin/env bash
# ROS 1 packages the nav_base example's ROS 1 simulation and tests need beyond setup-ros1.sh: actionlib (its
# action servers and clients; Debian pulls rospy in with it) and the nav_msgs/sensor_msgs Python modules
# (odometry, battery, laser), from Debian 12. Called by .ci/setup.sh --test with $SUDO set. Idempotent, quiet,
# and independent of the order the parts run in.
set -euo pipefail

SUDO="${SUDO-}"
. "$(dirname "${BASH_SOURCE[0]}")/apt.sh"  # apt_install: waits for another apt's locks
PACKAGES=(python3-actionlib python3-actionlib-msgs python3-nav-msgs python3-sensor-msgs ros-nav-msgs ros-sensor-msgs)

if ! command -v apt-get >/dev/null; then
  echo "setup-ros1-nav: no apt-get; install these Debian packages yourself: ${PACKAGES[*]}" >&2
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
    echo "setup-ros1-nav: could not install ${missing[*]}" >&2
    exit 1
  fi
fi

/usr/bin/python3 -c "import actionlib, actionlib_msgs.msg, nav_msgs.msg, sensor_msgs.msg" \
  || { echo "setup-ros1-nav: actionlib/nav_msgs/sensor_msgs are not importable by /usr/bin/python3" >&2; exit 1; }
