"""Stubs of the sensor_msgs interfaces sensor_head_adaptor uses (partial)."""
