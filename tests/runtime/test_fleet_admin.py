"""Admin requests under the broker ACL the events backend writes (issue 32), on a real mosquitto with users: the
fleet's admin adds a robot to a running fleet and removes it again, the edge node (user = robot id) answers;
a signed request from a user the ACL does not let ask is dropped by the broker, and a stranger reads no answer.
The robots are simulated (`SimPort`): what is under test is the bus, the ACL and the fleet, not ROS (the ROS 2
path is test_fleet_changes_ros2.py's).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from td2adaptor.backends.events.generator import generate as events
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from td2adaptor.runtime.config import RuntimeConfig, load_defaults, robot_config
from td2adaptor.runtime.events import now_rfc3339
from td2adaptor.runtime.node.admin import Admin, admin_bus, admin_topics, sign
from td2adaptor.runtime.node.fleet import Fleet
from td2adaptor.runtime.node.roslink import RosLink
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import GOAL, sim, td_with_security, terminal

ROBOT = "adm_robot"
KEY = "the-admin-key-of-site-9-for-tests"


def test_admin_requests_through_the_generated_acl(tmp_path: Path) -> None:
    model = td_with_security(tmp_path, {"basic_sc": {"scheme": "basic"}})
    diags = Diagnostics()
    tree = events(model, GenOptions(extra=(("events.robots", [ROBOT]), ("events.fleet", "site_9"))), diags)
    assert not list(diags)
    acl = tmp_path / "mosquitto.acl"
    acl.write_bytes(tree.files[f"{model.package_name}/mosquitto.acl"])
    users = {ROBOT: "node-pass", "fleet-admin": "admin-pass", "application": "app-pass", "intruder": "x-pass"}
    broker = Mosquitto(tmp_path / "broker", users=users, acl=acl)
    broker.start()
    settings = {"bus": broker.url, "poll_period": 0.05, "property_period": 0, "state_dir": "", "fleet": "site_9"}
    defaults = load_defaults(env={}, overrides={**settings, "username": ROBOT, "password": "node-pass"})
    defaults["fleet_admin_key"] = KEY

    def grow(configs: Sequence[RuntimeConfig]) -> RosLink:
        return RosLink(ports={c.robot: SimPort(model, sim(0.05)) for c in configs})

    fleet = Fleet(model, RosLink(grow=grow), distro="ros2")
    template = robot_config(defaults, "stand-in")
    admin = Admin(
        fleet,
        admin_bus(template, model),
        name="site_9",
        root="td2adaptor",
        key=KEY,
        make_config=lambda robot, namespace: robot_config(defaults, robot, namespace),
        freshness_window=60,
        clock_skew=5,
    )
    clients: list[AppClient] = []
    try:
        admin.start()
        request, answer = admin_topics("td2adaptor", "site_9")
        boss = AppClient(broker, [answer], username="fleet-admin", password="admin-pass")
        clients.append(boss)
        app = AppClient(broker, ["td2adaptor/#"], username="application", password="app-pass")
        clients.append(app)
        intruder = AppClient(broker, ["td2adaptor/#"], username="intruder", password="x-pass")
        clients.append(intruder)

        def answers(client: AppClient) -> list[dict[str, Any]]:
            return [e for t, e in list(client.events) if t == answer]

        # the application knows the key (say it leaked), but the ACL does not let it ask: the broker drops it
        app.send(request, sign({"id": "by-app", "time": now_rfc3339(), "op": "add", "robot": ROBOT}, KEY))
        boss.send(request, sign({"id": "add-1", "time": now_rfc3339(), "op": "add", "robot": ROBOT}, KEY))
        boss.wait(lambda _ev: len(answers(boss)) == 1, timeout=20)
        added = answers(boss)[0]
        assert (added["correlation"], added["payload"]["code"]) == ("add-1", "added"), added
        assert admin.answered == {"added": 1}  # the application's request never reached the node
        app.wait(lambda ev: any(t == f"td2adaptor/{ROBOT}/status" for t, _ in ev), timeout=20)
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoRun", {"correlation": "m1", "payload": GOAL})
        app.wait(terminal("feedback", "m1"), timeout=20)

        boss.send(request, sign({"id": "rm-1", "time": now_rfc3339(), "op": "remove", "robot": ROBOT}, KEY))
        boss.wait(lambda _ev: len(answers(boss)) == 2, timeout=20)
        assert answers(boss)[1]["payload"]["code"] == "removed"
        assert fleet.robots() == {}
        assert until(lambda: _last_state(app) == "offline", 10)
        assert answers(app) and not answers(intruder)  # the application may read answers; a stranger not
    finally:
        for client in clients:
            client.close()
        admin.stop()
        fleet.stop()
        broker.stop()


def _last_state(app: AppClient) -> str | None:
    states = [e["payload"]["state"] for t, e in list(app.events) if t == f"td2adaptor/{ROBOT}/status"]
    return states[-1] if states else None
