"""The simulated nav_base for tests and demos: `core` has the base's behaviour, `ros2`/`ros1` serve it."""
