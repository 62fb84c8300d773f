"""Stubs of the geometry_msgs interfaces nav_base_adaptor uses (partial)."""
