"""Stubs of the nav_msgs interfaces nav_base_adaptor uses (partial)."""
