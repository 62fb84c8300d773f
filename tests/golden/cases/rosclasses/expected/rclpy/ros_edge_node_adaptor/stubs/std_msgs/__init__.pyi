"""Stubs of the std_msgs interfaces ros_edge_node_adaptor uses (partial)."""
