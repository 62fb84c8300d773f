"""An adaptor in its own process (so a test can kill it):
`python -m tests.runtime.engine_proc URL ROBOT [MQTT_VERSION]`."""

from __future__ import annotations

import sys
import time

from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import rb1_model, sim


def main() -> None:
    url, robot = sys.argv[1], sys.argv[2]
    version = sys.argv[3] if len(sys.argv) > 3 else "5"
    model = rb1_model()
    serve(model, SimPort(model, sim()), RuntimeConfig(robot=robot, bus=url, property_period=0, mqtt_version=version))
    print("ready", flush=True)
    while True:
        time.sleep(60)


if __name__ == "__main__":
    main()
