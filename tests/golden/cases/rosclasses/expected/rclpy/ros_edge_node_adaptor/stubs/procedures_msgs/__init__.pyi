"""Stubs of the procedures_msgs interfaces ros_edge_node_adaptor uses (partial)."""
