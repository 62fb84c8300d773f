"""Stubs of the ar_track_alvar_msgs interfaces rb1_base_b_adaptor uses (partial)."""
