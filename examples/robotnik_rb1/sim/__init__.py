"""A simulated Robotnik RB-1 for tests and demos: `core` has the robot's behaviour, `ros2`/`ros1` serve it."""
