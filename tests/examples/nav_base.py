"""What the nav_base tests share besides fixtures (test modules import from here, never from nav_base_fixtures)."""

from __future__ import annotations

from tests.ros2 import env

EXAMPLE = env.REPO / "examples" / "nav_base"
INTERFACES = EXAMPLE / "interfaces"
PACKAGE = "nav_base_adaptor"
#: one simulated base per test that drives (each test starts from an idle base at the origin)
BASES = tuple(f"nav_test_{i}" for i in range(8))
SPEED = 2.0  # m/s
FEEDBACK_RATE = 20.0
