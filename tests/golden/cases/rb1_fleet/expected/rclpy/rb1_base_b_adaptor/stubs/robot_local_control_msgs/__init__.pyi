"""Stubs of the robot_local_control_msgs interfaces rb1_base_b_adaptor uses (partial)."""
