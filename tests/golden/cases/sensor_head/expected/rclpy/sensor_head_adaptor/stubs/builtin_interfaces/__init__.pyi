"""Stubs of the builtin_interfaces interfaces sensor_head_adaptor uses (partial)."""
