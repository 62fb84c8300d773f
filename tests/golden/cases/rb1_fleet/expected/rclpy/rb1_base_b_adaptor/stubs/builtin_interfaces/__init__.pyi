"""Stubs of the builtin_interfaces interfaces rb1_base_b_adaptor uses (partial)."""
