"""Stubs of the std_msgs interfaces robotnik_rb_1_adaptor uses (partial)."""
