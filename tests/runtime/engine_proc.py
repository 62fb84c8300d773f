"""An adaptor in its own process (so a test can kill it):
`python -m tests.runtime.engine_proc URL ROBOT [MQTT_VERSION [STATE_DIR RUNS_FILE]]`; with a state directory and
a runs file, each mission the robot starts is appended to RUNS_FILE (as tests/runtime/share_proc.py does)."""

from __future__ import annotations

import os
import sys
import time

from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import rb1_model, sim


def main() -> None:
    url, robot = sys.argv[1], sys.argv[2]
    version = sys.argv[3] if len(sys.argv) > 3 else "5"
    model = rb1_model()
    config = RuntimeConfig(robot=robot, bus=url, property_period=0, mqtt_version=version)
    port = SimPort(model, sim())
    if len(sys.argv) > 5:
        from tests.runtime.share_proc import LoggedPort

        LoggedPort.runs_fd = os.open(sys.argv[5], os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
        port = LoggedPort(model, sim())
        port.robot = robot
        config = RuntimeConfig(
            robot=robot, bus=url, property_period=0, presence_period=0, mqtt_version=version, state_dir=sys.argv[4]
        )
    serve(model, port, config)
    print("ready", flush=True)
    while True:
        time.sleep(60)


if __name__ == "__main__":
    main()
