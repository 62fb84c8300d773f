"""Stubs of the builtin_interfaces interfaces ros_edge_node_adaptor uses (partial)."""
