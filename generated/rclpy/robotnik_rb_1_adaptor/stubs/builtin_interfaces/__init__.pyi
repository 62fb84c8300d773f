"""Stubs of the builtin_interfaces interfaces robotnik_rb_1_adaptor uses (partial)."""
