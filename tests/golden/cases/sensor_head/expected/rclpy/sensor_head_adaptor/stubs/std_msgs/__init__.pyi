"""Stubs of the std_msgs interfaces sensor_head_adaptor uses (partial)."""
