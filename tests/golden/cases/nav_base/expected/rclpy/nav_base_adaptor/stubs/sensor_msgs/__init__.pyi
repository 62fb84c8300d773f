"""Stubs of the sensor_msgs interfaces nav_base_adaptor uses (partial)."""
