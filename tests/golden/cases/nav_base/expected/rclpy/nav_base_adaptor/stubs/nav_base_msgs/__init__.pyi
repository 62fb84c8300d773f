"""Stubs of the nav_base_msgs interfaces nav_base_adaptor uses (partial)."""
