"""The screenshot in docs/dashboard.md: the page with the warehouse demo running (`td2adaptor demo warehouse
--bus mqtt://...`, ROS 2 Jazzy from PyPI, each edge node its own process), taken by headless Chromium once
the robots are on the map and rb1_base_a has had a mission:
`python -m tests.dashboard.screenshot [docs/dashboard.png]`."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from tests.conftest import REPO
from tests.dashboard.harness import chromium, css, dashboard, wait
from tests.runtime.broker import Mosquitto

ROBOT = "rb1_base_a"


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else REPO / "docs" / "dashboard.png")
    with tempfile.TemporaryDirectory() as tmp:
        broker = Mosquitto(Path(tmp) / "broker")
        broker.start()
        demo = None
        try:
            with dashboard(broker.url) as dash, chromium() as driver:
                driver.set_window_size(1280, 1000)
                driver.get(f"{dash.url}#/robot/{ROBOT}")
                demo = subprocess.Popen(
                    [sys.executable, "-m", "td2adaptor", "demo", "warehouse", "--bus", broker.url, "--duration", "4"],
                    cwd=REPO,
                    env=dict(os.environ),
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    start_new_session=True,  # its edge nodes and simulations with it, in one process group
                )
                wait(driver, lambda d: len(css(d, "#map g.robot")) >= 3, 240, "three robots on the map")
                wait(driver, lambda d: css(d, '#timeline li[data-terminal="true"]'), 240, "a finished mission")
                wait(driver, lambda d: css(d, '#timeline li[data-terminal="false"][data-mission]'), 240, "a new one")
                driver.save_screenshot(str(out))
        finally:
            if demo is not None:  # the demo, its edge nodes and simulations, while the broker is still there
                os.killpg(demo.pid, signal.SIGTERM)
                try:
                    demo.wait(30)
                except subprocess.TimeoutExpired:
                    pass
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(demo.pid, signal.SIGKILL)
                demo.wait(10)
            broker.stop()
    print(f"{out}: {out.stat().st_size} bytes")


if __name__ == "__main__":
    main()
