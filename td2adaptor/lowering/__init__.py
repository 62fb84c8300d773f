"""Lowering: the raw ROS bindings the front end extracted → the canonical model.

Checks ROS graph names (rosnames.py), groups affordances into components, links procedures, resolves every
type for ROS 1 and ROS 2 and cross-checks the TD's data schemas against the messages (crosscheck.py).
"""
