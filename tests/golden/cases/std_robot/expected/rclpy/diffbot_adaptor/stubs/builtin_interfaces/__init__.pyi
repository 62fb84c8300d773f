"""Stubs of the builtin_interfaces interfaces diffbot_adaptor uses (partial)."""
