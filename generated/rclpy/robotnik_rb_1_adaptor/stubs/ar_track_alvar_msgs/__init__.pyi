"""Stubs of the ar_track_alvar_msgs interfaces robotnik_rb_1_adaptor uses (partial)."""
