"""Stubs of the sensor_msgs interfaces diffbot_adaptor uses (partial)."""
