"""Stubs of the robotnik_msgs interfaces rb1_base_b_adaptor uses (partial)."""
