"""Stubs of the robot_local_control_msgs interfaces ros_edge_node_adaptor uses (partial)."""
