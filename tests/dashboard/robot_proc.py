"""A simulated RB-1 behind its edge node in a process of its own, for a test to kill:
`python -m tests.dashboard.robot_proc URL ROBOT` (credentials from TD2ADAPTOR_MQTT_* as `run` reads them)."""

from __future__ import annotations

import sys
import time

from tests.dashboard.harness import serve_robot


def main() -> None:
    serve_robot(sys.argv[1], sys.argv[2], duration=1.0)
    print("ready", flush=True)
    while True:
        time.sleep(60)


if __name__ == "__main__":
    main()
