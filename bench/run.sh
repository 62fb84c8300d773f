#!/usr/bin/env bash
# All benchmarks, one command: bash bench/run.sh
# Each script prints its figures next to a baseline measured in the same run. Benchmarks whose middleware
# is not installed (ROS 1, ROS 2, mosquitto, arm-none-eabi) say so and are skipped; the rest still run.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
status=0
# the peer generator the issue-3 comparison needs
[ -x .venv/bin/datamodel-codegen ] || "$PY" -m pip install -q -e '.[bench]' >/dev/null 2>&1 || true
run() {
  echo
  echo "== $1"
  shift
  "$@" || { echo "(failed: exit $?)"; status=1; }
}
run "front end (issue 2)" "$PY" bench/frontend.py
[ -f bench/workflow.py ] && run "workflow: check and gen (issue 6)" "$PY" bench/workflow.py
[ -f bench/startup_scale.py ] && run "a first validate, and gen as the TD grows (issue 34)" "$PY" bench/startup_scale.py
[ -f bench/backend_rclpy.py ] && run "rclpy backend (issue 3)" "$PY" bench/backend_rclpy.py
[ -f bench/backend_rospy.py ] && run "rospy backend (issue 3)" "$PY" bench/backend_rospy.py
run "gen next to a peer generator (issue 3)" "$PY" bench/peer.py
[ -f bench/backend_mros.py ] && run "mROS backend (issue 4)" "$PY" bench/backend_mros.py
[ -f bench/runtime_bus.py ] && run "edge-node runtime over MQTT (issue 5)" "$PY" bench/runtime_bus.py
[ -f bench/edge_node_ros2.py ] && run "edge node: MQTT event -> ROS 2 call -> feedback (issue 5)" "$PY" bench/edge_node_ros2.py
[ -f bench/edge_node_ros1.py ] && run "edge node: MQTT event -> ROS 1 bridge -> answer, vs direct rospy call + echo (issue 31)" "$PY" bench/edge_node_ros1.py
[ -f bench/wot_consumer.py ] && run "a WoT consumer (node-wot) on ROS 2; the retained TD at start (issue 11)" "$PY" bench/wot_consumer.py
[ -f bench/discovery.py ] && run "discovery: TD registered with a TD directory at start (issue 11)" "$PY" bench/discovery.py
[ -f bench/td_size.py ] && run "the examples' published TDs: JSON, RDF, and what a TD directory gives back (issue 35)" "$PY" bench/td_size.py
[ -f bench/scaffold.py ] && run "scaffold a 100-node ROS 2 graph (issue 15)" "$PY" bench/scaffold.py
[ -f bench/edge_node_actions_ros2.py ] && run "edge node: ROS 2 action goal -> feedback and result events (issue 12)" "$PY" bench/edge_node_actions_ros2.py
[ -f bench/fleet_ros2.py ] && run "a fleet of 100 robots on one broker: one edge node per robot, one for the fleet (issue 17)" "$PY" bench/fleet_ros2.py
[ -f bench/sensor_stream_ros2.py ] && run "sensor streams (odom 100 Hz, scan 10 Hz) as property events (issue 17)" "$PY" bench/sensor_stream_ros2.py
[ -f bench/service_clients_ros2.py ] && run "concurrent calls to one ROS 2 service through the generated adaptor (issue 17)" "$PY" bench/service_clients_ros2.py
[ -f bench/chaos.py ] && run "chaos: 5,000 bad events answered, missions through broker restarts and SIGKILLs (issue 30)" "$PY" bench/chaos.py
exit $status
