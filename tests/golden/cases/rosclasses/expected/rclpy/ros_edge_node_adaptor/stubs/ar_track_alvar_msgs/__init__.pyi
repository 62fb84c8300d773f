"""Stubs of the ar_track_alvar_msgs interfaces ros_edge_node_adaptor uses (partial)."""
