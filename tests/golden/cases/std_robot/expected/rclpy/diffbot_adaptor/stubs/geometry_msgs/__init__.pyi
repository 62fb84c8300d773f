"""Stubs of the geometry_msgs interfaces diffbot_adaptor uses (partial)."""
