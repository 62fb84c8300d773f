"""A process of a shared fleet that hangs and resumes handles nothing it read on a connection whose session
another process took over meanwhile (issue 32, docs/fleet.md "Several processes share a fleet"). SIGSTOP leaves
its connections open: the broker goes on writing a robot's commands into the socket, where they wait, unread
and unacknowledged, while the other process takes the robot (and its session, whose commands the broker then
delivers to it). On SIGCONT the hung process reads those commands before the broker's "Session taken over"
behind them; it must not run them again (across hosts nothing else stops it: no shared state directory).
The same holds for ROS action goals (`SHARE_ACTIONS`: the robots' action is a ROS action served by simulated
action servers): a goal is sent only once the broker has the invoke's admitted entry (node/admitted.py), and not
at all when the robot's connection was lost by then; the wait is a callback of the broker's acknowledgement, not
a wait on the engine's loop (engine/goals.py `gate`). The processes are tests/runtime/share_proc.py's, with state
directories apart, as on two hosts.
"""

from __future__ import annotations

import signal
import subprocess
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import orjson
import pytest

from td2adaptor.runtime.events import now_rfc3339
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.test_fleet_share import INVOKE, Procs, Watcher, retained, served_by, shares

ROBOTS = 4
GOAL = "td2adaptor/{robot}/MathComponent/fibonacci"


def procedure(n: int) -> dict[str, Any]:
    return {"procedure": {"goals": [{"pose": {"x": 7.0 + n / 100, "y": 3.0}}]}}


def goal(n: int) -> dict[str, Any]:
    return {"order": 3 + n}


@dataclass
class Hosts:
    """Two share_proc processes with state directories apart, as on two hosts, that share the ROBOTS robots, two
    each: `frozen` is the one a test hangs."""

    broker: Mosquitto
    procs: Procs
    watcher: Watcher
    sender: AppClient
    frozen: subprocess.Popen[str]
    other: subprocess.Popen[str]

    def parts(self) -> tuple[Mosquitto, Procs, Watcher, AppClient, subprocess.Popen[str], subprocess.Popen[str]]:
        return self.broker, self.procs, self.watcher, self.sender, self.frozen, self.other

    def settled(self) -> bool:
        """Each process serves two of the robots."""
        pids = {self.frozen.pid, self.other.pid}
        return served_by(self.watcher, pids, ROBOTS) and set(shares(self.watcher, pids).values()) == {2}

    def robots_of(self, proc: subprocess.Popen[str]) -> list[str]:
        return [r for r, (_s, pid) in self.watcher.owners().items() if pid == proc.pid]


def stop(proc: subprocess.Popen[str]) -> None:
    """SIGSTOP `proc`, and wait until every thread of it has stopped: the kernel wakes one thread to take a stop
    signal, which stops the others once it runs, so on a loaded machine the others go on for a while (a command
    sent right after the signal was admitted 7 ms later in one loop run, and its goal never sent: that process
    stopped while its gate waited, and the other ended it `failed` with the takeover's words)."""
    proc.send_signal(signal.SIGSTOP)
    tasks = Path(f"/proc/{proc.pid}/task")

    def state(stat: Path) -> str:
        try:
            return stat.read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            return "T"  # a thread that ended meanwhile

    assert until(lambda: all(state(t / "stat") in ("T", "t") for t in tasks.iterdir()), 20)


@contextmanager
def two_hosts(tmp_path: Path) -> Iterator[Hosts]:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    procs = Procs(broker, tmp_path, ROBOTS, hosts=True)
    watcher = Watcher(broker)
    sender = AppClient(broker, ["test/nothing"])
    try:
        hosts = Hosts(broker, procs, watcher, sender, *procs.start_many(2))
        assert until(hosts.settled, 60), procs.logs()
        yield hosts
    finally:
        sender.close()
        watcher.close()
        procs.close()
        broker.stop()


@pytest.mark.parametrize(
    ("actions", "topic", "payload"),
    [pytest.param("", INVOKE, procedure, id="procedure"), pytest.param("1", GOAL, goal, id="ros-action-goal")],
)
def test_a_resumed_process_runs_nothing_it_read_on_a_session_taken_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, actions: str, topic: str, payload: Any
) -> None:
    monkeypatch.setenv("SHARE_ACTIONS", actions)
    with two_hosts(tmp_path) as hosts:
        broker, procs, watcher, sender, frozen, other = hosts.parts()
        theirs, others = hosts.robots_of(frozen), hosts.robots_of(other)
        stopped = time.monotonic()  # what came before (the first shares' hand-overs) is no grab
        try:
            stop(frozen)
            sent = []
            for n, robot in enumerate(theirs):  # one each (a robot runs one at a time), into the hung process's
                event_id = uuid.uuid4().hex  # socket: read by nobody yet
                # each robot's its own command (the runs file tells them apart)
                event = {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": payload(n)}
                sender.send(topic.format(robot=robot), event)
                sent.append(event_id)
            assert until(lambda: served_by(watcher, {other.pid}, ROBOTS), 20), (watcher.owners(), procs.logs())
            # the broker gives the session's commands to the next owner, which runs them
            assert until(lambda: set(sent) <= set(watcher.terminals()), 30), procs.logs()
            ends = {i: watcher.terminals()[i] for i in sent}
            assert sorted(procs.runs_of().values()) == [1, 1], (procs.runs_of(), ends, procs.logs())
        finally:
            frozen.send_signal(signal.SIGCONT)
        # it lets the robot go, takes a share again by hand-over, and runs none of the commands a second time
        assert until(hosts.settled, 30), (
            watcher.owners(),
            procs.logs(),
        )
        time.sleep(2)  # a second run would have been written by now (a mission starts within milliseconds)
        runs = procs.runs_of()
        assert sorted(runs.values()) == [1, 1], (runs, procs.logs())
        # nor, finding the other's beats old (they waited unread in its socket), did it take the other's robots:
        # the silence was its own (a robot of the other's that was the hung one's before, when the shares were first
        # made, is no grab)
        grabbed = {
            r
            for t, r, p in watcher.statuses()
            if t > stopped and r in others and (p.get("owner") or {}).get("pid") == frozen.pid
        }
        assert not grabbed, (grabbed, procs.logs())
        # and what the broker keeps of each command for a later owner (node/admitted.py) is the other's, which ran
        # it, finished (its terminal event is the one the application got): the hung process's own entry (admitted,
        # never run) did not stay, nor did the end its stop gave it (`failed`, "retired": recorded over the other's
        # when its robot's session was found taken before its goal's gate had put the other's entry back). When
        # the robot came back to the hung process by hand-over before the other had marked the entry done, the hung
        # one adopted it (its recovery ends it): then it is the hung one's, finished too
        members = retained(broker, "td2adaptor/.fleet/shared/members/+")
        node = {e["owner"]["pid"]: e["owner"]["node"] for e in members.values() if e}

        def admitted() -> dict[str, Any]:
            return {e["id"]: e for e in retained(broker, "td2adaptor/.fleet/shared/admitted/+/+").values() if e}

        def kept() -> dict[str, tuple[str | None, str | None]]:
            entries = admitted()
            return {i: (entries.get(i, {}).get("owner"), entries.get(i, {}).get("state")) for i in sent}

        # the hung process puts the other's entry back once its robot's connection stopped serving, and again once
        # its goal's gate settles, which may come after the hand-over settled
        assert until(lambda: {state for _owner, state in kept().values()} == {"finished"}, 20), (kept(), procs.logs())
        entries = admitted()
        assert {owner for owner, _state in kept().values()} <= {node[other.pid], node[frozen.pid]}, (kept(), node)
        adopted = [i for i in sent if entries[i]["owner"] == node[frozen.pid]]
        assert all("latest" in entries[i] for i in adopted), [entries[i] for i in adopted]  # adopted, not its own


def test_a_resumed_process_leaves_the_entry_of_a_goal_taken_over_to_its_new_owner(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A goal runs when its process hangs; another takes the robot over and ends the goal (its own action servers
    cannot follow it): its terminal event is the one the application gets, and the admitted entry the broker keeps
    for a later owner (answered again from it) is the new owner's. On SIGCONT the hung process finds the robot's
    session taken and stops serving it: the goal it still had in flight is not its to end, on the bus nor in the
    entry (its "retired" end, recorded over the new owner's, stayed: a resend would be answered with a terminal
    event nobody had received)."""
    monkeypatch.setenv("SHARE_ACTIONS", "1")
    with two_hosts(tmp_path) as hosts:
        broker, procs, watcher, sender, frozen, other = hosts.parts()
        robot = hosts.robots_of(frozen)[0]
        event_id = uuid.uuid4().hex  # a goal of 2000 steps of 0.05 s: still running long after the test
        sender.send(
            GOAL.format(robot=robot),
            {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": {"order": 2000}},
        )

        def states() -> list[str]:
            return [
                str(e["payload"].get("state"))
                for _t, topic, e in watcher.timed()
                if topic.endswith("/feedback") and e.get("correlation") == event_id
            ]

        assert until(lambda: "running" in states(), 30), procs.logs()
        try:
            stop(frozen)
            assert until(lambda: served_by(watcher, {other.pid}, ROBOTS), 20), (watcher.owners(), procs.logs())
            assert until(lambda: event_id in watcher.terminals(), 30), procs.logs()
        finally:
            frozen.send_signal(signal.SIGCONT)
        assert until(hosts.settled, 30), (
            watcher.owners(),
            procs.logs(),
        )
        members = retained(broker, "td2adaptor/.fleet/shared/members/+")
        node = {e["owner"]["pid"]: e["owner"]["node"] for e in members.values() if e}
        (ended,) = watcher.terminals()[event_id]  # one terminal event: the new owner's
        assert ended["state"] == "failed", ended

        def entry() -> dict[str, Any]:
            entries = retained(broker, "td2adaptor/.fleet/shared/admitted/+/+").values()
            return next((e for e in entries if e and e.get("id") == event_id), {})

        # the hung process's stop of the robot (halted, taken over) is behind the settled shares; its entry, had it
        # written one, would be on the broker before the shares settled (the member connection's order)
        kept = entry()
        assert (kept.get("owner"), kept.get("phase")) == (node[other.pid], "done"), (kept, node, procs.logs())
        assert orjson.loads(kept["latest"])["payload"]["message"] == ended["message"], kept
