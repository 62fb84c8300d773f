"""Stubs of the geometry_msgs interfaces ros_edge_node_adaptor uses (partial)."""
