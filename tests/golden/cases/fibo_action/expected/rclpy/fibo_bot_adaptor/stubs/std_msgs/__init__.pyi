"""Stubs of the std_msgs interfaces fibo_bot_adaptor uses (partial)."""
