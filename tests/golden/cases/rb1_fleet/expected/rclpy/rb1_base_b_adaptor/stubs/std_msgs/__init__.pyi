"""Stubs of the std_msgs interfaces rb1_base_b_adaptor uses (partial)."""
