"""Helpers and helper nodes for the real ROS 1 (rospy) tests."""
