"""A shared fleet meets robots that processes outside it served (issue 32, found by a new user with a conveyor
fleet): a robot whose last owner was a plain `run` that stopped is started by the share, not "taken over" (the
member record and `fleet status` listed such takeovers at every fresh start); a robot a live process outside the
share serves is not served, and the share says so once instead of waiting in silence for ever; the log names
where a shared robot came from. Real mosquitto, tests/runtime/share_proc.py's processes (robots simulated)."""

from __future__ import annotations

import json
import os
import socket
import time
from pathlib import Path

from td2adaptor.runtime.node.owner import this_process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.share_proc import FLEET
from tests.runtime.test_fleet_share import Procs, Watcher, retained

ROBOTS = 4
GONE_PID = 4_194_000  # above any pid this machine gives out (pid_max is at most 4,194,304): no such process


def status(state: str, pid: int, node: str) -> dict[str, object]:
    started = this_process().started if pid == os.getpid() else "2026-01-01T00:00:00Z"  # what `lives` compares
    owner = {"host": socket.gethostname(), "pid": pid, "started": started, "node": node}
    return {"type": "status", "payload": {"state": state, "thing": "RB-1", "owner": owner}}


def test_a_shared_fleet_starts_robots_outsiders_left_and_says_why_it_leaves_one_an_outsider_serves(
    tmp_path: Path,
) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    writer = AppClient(broker, ["nothing/#"])
    # rb_00: its last owner, a plain `run`, stopped (offline); rb_01: a plain `run` of this test's process serves it
    for robot, state, pid, node in (
        ("rb_00", "offline", GONE_PID, "a1" * 8),
        ("rb_01", "online", os.getpid(), "b2" * 8),
    ):
        info = writer.client.publish(f"td2adaptor/{robot}/status", json.dumps(status(state, pid, node)), 1, True)
        info.wait_for_publish(10)
    procs = Procs(broker, tmp_path, ROBOTS)
    watcher = Watcher(broker)
    try:
        (proc,) = procs.start_many(1)
        others = {"rb_00", "rb_02", "rb_03"}

        def served() -> bool:
            owners = watcher.owners()
            return all(owners.get(r) == ("online", proc.pid) for r in others)

        assert until(served, 30), (watcher.owners(), procs.logs())
        time.sleep(1.0)  # a few rounds of the share
        assert watcher.owners()["rb_01"][1] == os.getpid()  # left to its live owner outside the share
        (record,) = [r for r in retained(broker, f"td2adaptor/.fleet/{FLEET}/members/+").values() if r]
        assert record["takeovers"] == [], record["takeovers"]  # a start, not a takeover
        log = procs.logs()
        said = [line for line in log.splitlines() if "is no member of the fleet" in line]
        assert len(said) == 1 and "robot rb_01: not served by fleet shared:" in said[0], said
        assert f"process {os.getpid()} on {socket.gethostname()}" in said[0] and "--share" in said[0], said
        assert "robot rb_00: served from now on (shared, file)" in log, log
    finally:
        watcher.close()
        writer.close()
        procs.close()
        broker.stop()
