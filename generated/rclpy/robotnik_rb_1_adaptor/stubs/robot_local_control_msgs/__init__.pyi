"""Stubs of the robot_local_control_msgs interfaces robotnik_rb_1_adaptor uses (partial)."""
