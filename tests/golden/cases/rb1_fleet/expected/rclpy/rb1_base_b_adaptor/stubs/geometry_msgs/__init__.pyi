"""Stubs of the geometry_msgs interfaces rb1_base_b_adaptor uses (partial)."""
