"""Stubs of the std_msgs interfaces nav_base_adaptor uses (partial)."""
