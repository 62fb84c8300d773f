"""Stubs of the geometry_msgs interfaces sensor_head_adaptor uses (partial)."""
