"""Helpers for the real-runtime ROS 2 tests: isolation, building interfaces and packages, fixtures."""
