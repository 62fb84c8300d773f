"""Build genpy modules for interface folders with ROS 1 actions: `build_actions.py ROOT OUT` (Debian's Python).

The tests' short way to `td2adaptor.support.ros1build.generate` (msg, srv and the seven genaction messages of
each action) into a folder of their own, uncached: td2adaptor's runtime module, so every ROS 1 action test also
exercises what users build their interfaces with (`python -m td2adaptor.support.ros1build`).
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the module needs only the standard library

from td2adaptor.support.ros1build import BuildError, generate  # noqa: E402

if __name__ == "__main__":
    try:
        generate(Path(sys.argv[1]), Path(sys.argv[2]))
    except BuildError as exc:
        raise SystemExit(f"build_actions: {exc}") from None
    print("built", sys.argv[2])
