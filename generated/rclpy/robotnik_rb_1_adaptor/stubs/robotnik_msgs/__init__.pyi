"""Stubs of the robotnik_msgs interfaces robotnik_rb_1_adaptor uses (partial)."""
