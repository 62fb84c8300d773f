"""Stubs of the test_msgs interfaces fibo_bot_adaptor uses (partial)."""
