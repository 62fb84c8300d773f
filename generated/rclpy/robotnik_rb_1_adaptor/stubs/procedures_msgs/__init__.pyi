"""Stubs of the procedures_msgs interfaces robotnik_rb_1_adaptor uses (partial)."""
