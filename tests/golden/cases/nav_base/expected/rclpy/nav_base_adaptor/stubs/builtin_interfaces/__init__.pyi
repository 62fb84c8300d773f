"""Stubs of the builtin_interfaces interfaces nav_base_adaptor uses (partial)."""
