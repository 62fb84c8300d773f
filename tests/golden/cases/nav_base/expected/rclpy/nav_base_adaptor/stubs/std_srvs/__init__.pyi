"""Stubs of the std_srvs interfaces nav_base_adaptor uses (partial)."""
