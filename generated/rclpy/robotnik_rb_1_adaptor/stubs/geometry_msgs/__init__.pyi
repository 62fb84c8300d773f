"""Stubs of the geometry_msgs interfaces robotnik_rb_1_adaptor uses (partial)."""
