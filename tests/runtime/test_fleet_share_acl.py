"""`run --share` under the broker ACL the events backend writes (issue 32): on a real mosquitto that enforces it,
with every robot's edge node connecting as its own user (the robot id) and each process's member connection as
its top-level user (a robot's), two processes share the robots, the survivor takes a killed one's robots over,
and a user the ACL gives no grant cannot forge a member record (which would take a share of the robots).
The processes are tests/runtime/share_proc.py's (robots simulated): what is under test is the ACL.
"""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.backends.events.generator import generate as events
from td2adaptor.diagnostics import Diagnostics
from td2adaptor.generation.backend import GenOptions
from td2adaptor.runtime.node.shareplan import members_topic
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import td_with_security
from tests.runtime.share_proc import FLEET
from tests.runtime.test_fleet_share import Procs, Watcher, served_by, shares

ROBOTS = [f"rb_{i:02d}" for i in range(4)]
APP = ("application", "app-pass")


class AppWatcher(Watcher):
    """The Watcher, as the `application` user (the broker takes no anonymous client)."""

    def __init__(self, broker: Mosquitto) -> None:
        self.times: list[float] = []
        AppClient.__init__(self, broker, ["td2adaptor/#"], username=APP[0], password=APP[1])


def members(broker: Mosquitto) -> dict[str, dict[str, Any]]:
    """The retained member records, read as the application (`fleet status` reads them so)."""
    reader = AppClient(broker, [members_topic("td2adaptor", FLEET)], username=APP[0], password=APP[1])
    try:
        time.sleep(0.5)  # retained messages come right after the SUBACK, which the client waited for
        return {t.rsplit("/", 1)[1]: e for t, e in list(reader.events) if e}
    finally:
        reader.close()


def test_share_works_under_the_generated_acl_and_no_stranger_forges_a_member(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = td_with_security(tmp_path, {"basic_sc": {"scheme": "basic"}})
    diags = Diagnostics()
    tree = events(model, GenOptions(extra=(("events.robots", ROBOTS), ("events.fleet", FLEET))), diags)
    assert not list(diags)
    acl = tmp_path / "mosquitto.acl"
    acl.write_bytes(tree.files[f"{model.package_name}/mosquitto.acl"])
    passwords = {robot: f"{robot}-pass" for robot in ROBOTS}
    users = {**passwords, APP[0]: APP[1], "intruder": "x-pass"}
    broker = Mosquitto(tmp_path / "broker", users=users, acl=acl)
    broker.start()
    monkeypatch.setenv("SHARE_TD", str(tmp_path / "td.json"))
    monkeypatch.setenv("SHARE_PASSWORDS", json.dumps(passwords))
    procs = Procs(broker, tmp_path, robots=len(ROBOTS))
    watcher = AppWatcher(broker)
    try:
        a, b = procs.start_many(2)
        pids = {a.pid, b.pid}

        def halves() -> bool:
            return served_by(watcher, pids, len(ROBOTS)) and set(shares(watcher, pids).values()) == {2}

        assert until(halves, 30), (watcher.owners(), procs.logs())
        assert set(members(broker)) and all(len(r["robots"]) == 2 for r in members(broker).values()), members(broker)

        # the application and a user with no grant try to join with a record of their own (and a beat): the broker
        # drops both, so no process gives them a share
        for user, password in (APP, ("intruder", "x-pass")):
            forger = AppClient(broker, ["test/nothing"], username=user, password=password)
            record = {"owner": {"host": "evil", "pid": 1, "started": "2026-01-01T00:00:00Z", "node": f"evil-{user}"}}
            forger.client.publish(members_topic("td2adaptor", FLEET, f"evil-{user}"), json.dumps(record), 1, True)
            forger.client.publish(f"td2adaptor/.fleet/{FLEET}/beats/evil-{user}", b"{}", 0)
            time.sleep(0.5)
            forger.close()
        records = members(broker)
        assert len(records) == 2 and not [n for n in records if n.startswith("evil")], records

        # the robots admin requests added (retained on robots/<robot>): a robot's user writes an entry, another
        # robot's reads it; the application's entry never arrives
        entries = f"td2adaptor/.fleet/{FLEET}/robots/+"
        reader = AppClient(broker, [entries], username=ROBOTS[1], password=passwords[ROBOTS[1]])
        for user, password in ((ROBOTS[0], passwords[ROBOTS[0]]), APP):
            writer = AppClient(broker, ["test/nothing"], username=user, password=password)
            entry = {"robot": f"adm_{user}", "namespace": "ns"}
            writer.client.publish(entries.replace("+", f"adm_{user}"), json.dumps(entry), 1, True).wait_for_publish(5)
            writer.close()
        assert until(lambda: any(t.endswith(f"/adm_{ROBOTS[0]}") for t, _ in list(reader.events)), 10)
        time.sleep(0.5)
        assert [t.rsplit("/", 1)[1] for t, _ in list(reader.events)] == [f"adm_{ROBOTS[0]}"], reader.events
        reader.close()
        cleaner = AppClient(broker, ["test/nothing"], username=ROBOTS[0], password=passwords[ROBOTS[0]])
        cleaner.client.publish(entries.replace("+", f"adm_{ROBOTS[0]}"), b"", 1, True).wait_for_publish(5)
        cleaner.close()

        # kill -9 one: the other takes its robots over, through the ACL
        killed = time.monotonic()
        a.send_signal(signal.SIGKILL)
        a.wait(10)
        assert until(lambda: shares(watcher, {b.pid}).get(b.pid) == len(ROBOTS), 15), (watcher.owners(), procs.logs())
        print(f"taken over {time.monotonic() - killed:.2f} s after the kill")
        records = members(broker)
        assert [sorted(r["robots"]) for r in records.values()] == [ROBOTS], records
    finally:
        watcher.close()
        procs.close()
        broker.stop()
