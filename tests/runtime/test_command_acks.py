"""A command is acknowledged to the broker only once the engine took it (issue 32; mqttbus.py, engine.py): a process
killed after its MQTT client read a command but before its engine admitted it leaves the command in the robot's
session, and whoever connects next with that session (the process restarted, or the process of a shared fleet
that takes the robot over) gets it again and answers it. No command is lost without an answer, none runs twice.

The moment is made without a mock: the process is stopped (SIGSTOP) while a burst of commands for its robots
waits at the broker, continued (SIGCONT), and killed (SIGKILL) as soon as the first of them is answered, so that
its MQTT client has read well ahead of what its engine admitted. Real mosquitto, real processes
(tests/runtime/engine_proc.py, share_proc.py), each mission a robot starts written to one file.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import uuid
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime.events import now_rfc3339
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.test_fleet_share import INVOKE, Procs, Watcher, served_by, shares

#: commands sent to each robot while its process is stopped (a robot runs one mission at a time: the others are
#: answered `busy`, which is an answer too)
BURST = 40


def burst(broker: Mosquitto, robots: list[str], tag: int) -> dict[str, tuple[str, dict[str, Any]]]:
    """BURST invokes for each robot, each with its own id and a goal x no other has: id -> (topic, event)."""
    sender = AppClient(broker, ["test/nothing"])
    sent: dict[str, tuple[str, dict[str, Any]]] = {}
    try:
        for _ in range(BURST):
            for robot in robots:
                event_id = uuid.uuid4().hex
                x = tag + len(sent) / 1000
                event = {
                    "id": event_id,
                    "time": now_rfc3339(),
                    "correlation": event_id,
                    "payload": {"procedure": {"goals": [{"pose": {"x": x, "y": 3.0}}]}},
                }
                sent[event_id] = (INVOKE.format(robot=robot), event)
                sender.send(*sent[event_id])
    finally:
        sender.close()
    return sent


def kill_mid_burst(proc: subprocess.Popen[str], broker: Mosquitto, robots: list[str], watcher: Watcher) -> set[str]:
    """Stop `proc`, queue a burst for `robots`, continue it and kill it once it answered the first: the ids sent."""
    proc.send_signal(signal.SIGSTOP)
    try:
        sent = burst(broker, robots, 100)
    finally:
        proc.send_signal(signal.SIGCONT)
    assert until(lambda: set(sent) & set(watcher.terminals()), 20)
    proc.kill()
    proc.wait()
    answered = len(set(sent) & set(watcher.terminals()))
    print(f"killed after {answered} of {len(sent)} commands were answered")
    assert answered < len(sent)  # killed in the middle of the burst
    return set(sent)


def every_one_answered_once(sent: set[str], watcher: Watcher, runs: Counter[str], logs: str) -> None:
    def unanswered() -> set[str]:
        return sent - set(watcher.terminals())

    assert until(lambda: not unanswered(), 30), (f"{len(unanswered())} of {len(sent)} never answered", logs)
    ends = watcher.terminals()
    outcomes = {i: {(p["state"], p.get("seq")) for p in ends[i]} for i in sent}
    assert all(len(o) == 1 for o in outcomes.values()), [o for o in outcomes.values() if len(o) > 1][:5]
    assert runs and max(runs.values()) == 1, [k for k, n in runs.items() if n > 1]
    print(f"outcomes: {Counter(next(iter(o))[0] for o in outcomes.values())}; {sum(runs.values())} missions run")


def test_a_command_read_by_a_process_killed_before_it_admitted_it_is_answered_after_the_restart(
    tmp_path: Path,
) -> None:
    """One robot, one process (`serve`, the robot's own client id and persistent session), killed and started
    again: the broker gives the restarted process what the killed one had read and not taken."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    robot = "rb_acks"
    watcher = Watcher(broker)
    runs = tmp_path / "runs.txt"
    procs: list[subprocess.Popen[str]] = []

    def start() -> subprocess.Popen[str]:
        args = [broker.url, robot, broker.mqtt_version, str(tmp_path / "state"), str(runs)]
        log = (tmp_path / f"proc{len(procs)}.log").open("w")
        proc = subprocess.Popen(
            [sys.executable, "-m", "tests.runtime.engine_proc", *args], stdout=subprocess.PIPE, stderr=log, text=True
        )
        log.close()
        procs.append(proc)
        assert proc.stdout is not None and proc.stdout.readline().startswith("ready")
        return proc

    def logs() -> str:
        return "\n".join((tmp_path / f"proc{i}.log").read_text()[-3000:] for i in range(len(procs)))

    def counted() -> Counter[str]:
        lines = runs.read_text().splitlines() if runs.exists() else []
        return Counter(" ".join(line.split()[:2]) for line in lines)

    try:
        first = start()
        assert until(lambda: watcher.owners().get(robot, ("", None))[0] == "online", 20)
        sent = kill_mid_burst(first, broker, [robot], watcher)
        start()
        every_one_answered_once(sent, watcher, counted(), logs())
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
            if proc.stdout is not None:
                proc.stdout.close()
        watcher.close()
        broker.stop()


@pytest.mark.parametrize("hosts", [False, True], ids=["one-host", "two-hosts"])
def test_a_command_read_by_a_process_killed_before_it_admitted_it_is_answered_by_the_next_owner(
    tmp_path: Path, hosts: bool
) -> None:
    """Two processes of a shared fleet (share_proc.py; `two-hosts`: state directories apart, so what the killed one
    admitted reaches the next owner only through the broker, node/admitted.py): the survivor takes the killed
    one's robots and their sessions, and answers what the killed one had read and not taken."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    robots = 4
    procs = Procs(broker, tmp_path, robots, hosts=hosts)
    watcher = Watcher(broker)
    try:
        started = procs.start_many(2)
        pids = {p.pid for p in started}
        assert until(lambda: served_by(watcher, pids, robots) and set(shares(watcher, pids).values()) == {2}, 60)
        victim, survivor = started
        theirs = [r for r, (_s, pid) in watcher.owners().items() if pid == victim.pid]
        sent = kill_mid_burst(victim, broker, theirs, watcher)
        assert until(lambda: served_by(watcher, {survivor.pid}, robots), 20), procs.logs()
        every_one_answered_once(sent, watcher, procs.runs_of(), procs.logs())
    finally:
        watcher.close()
        procs.close()
        broker.stop()
