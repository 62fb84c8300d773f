"""Stubs of the nav_msgs interfaces diffbot_adaptor uses (partial)."""
