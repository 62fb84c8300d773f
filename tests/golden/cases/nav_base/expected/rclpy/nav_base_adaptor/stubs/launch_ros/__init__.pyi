# Type stubs of ROS 2's launch_ros, by td2adaptor: only what launch/edge_node.launch.py uses.
