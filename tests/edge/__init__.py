"""Helpers for the edge-node tests (td2adaptor run, GeneratedPort on real ROS, the demo)."""
