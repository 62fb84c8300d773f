"""What a new user ran into with the fleet features (issue 32), tried on ROS 1 with a robot nobody here wrote for
(a pan-tilt camera head) and consumed by wotpy: each test reproduces one finding on real parts (mosquitto, the
dashboard, simulated robots behind edge nodes) and holds the fix. The ROS 1 findings themselves are tested
beside the features they touch (test_presence_ros1.py, test_fleet_discovery_ros1.py).
"""

from __future__ import annotations

import json
import urllib.request
from typing import Any

from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until


def test_the_dashboard_keeps_a_robots_status_when_something_else_is_published_on_its_status_topic(
    broker: Mosquitto,
) -> None:
    """wotpy reads a property by publishing `{"action": "read"}` on the property's topic; the `presence` property's
    topic is the robot's status topic. The dashboard took that message for the robot's status: the robot lost its
    state (`{"time": null}`) until the next status."""
    from tests.dashboard.harness import dashboard, serve_robot
    from tests.dashboard.test_dashboard_browser import wait_for_robot

    robot = serve_robot(broker.url, "wotpy_read")
    app = AppClient(broker, ["td2adaptor/wotpy_read/status"], client_id="newuser-ros1-app")
    try:
        with dashboard(broker.url) as dash:
            wait_for_robot(dash.url, "wotpy_read")

            def summary() -> dict[str, Any]:
                with urllib.request.urlopen(f"{dash.url}api/fleet", timeout=5) as answer:
                    robots = json.loads(answer.read())["robots"]
                return next(r for r in robots if r["id"] == "wotpy_read")

            assert until(lambda: (summary()["status"] or {}).get("state") == "online", 20), summary()
            app.send("td2adaptor/wotpy_read/status", {"action": "read"})  # what wotpy's read_property sends
            app.send("td2adaptor/wotpy_read/status", b"not json")
            sentinel = {"type": "error", "time": "2026-11-28T00:00:00Z", "payload": {"code": "x", "message": "after"}}
            app.send("td2adaptor/wotpy_read/error", sentinel)  # sent after them: heard after them
            assert until(lambda: (summary()["lastError"] or {}).get("message") == "after", 20), summary()
            assert summary()["status"]["state"] == "online", summary()
    finally:
        app.close()
        robot.stop()
