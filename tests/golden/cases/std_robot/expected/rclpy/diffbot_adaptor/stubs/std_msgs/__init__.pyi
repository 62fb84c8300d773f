"""Stubs of the std_msgs interfaces diffbot_adaptor uses (partial)."""
