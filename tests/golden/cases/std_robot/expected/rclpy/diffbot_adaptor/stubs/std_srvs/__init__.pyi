"""Stubs of the std_srvs interfaces diffbot_adaptor uses (partial)."""
