"""Stubs of the robotnik_msgs interfaces ros_edge_node_adaptor uses (partial)."""
