"""The edges of a hand-over in a shared fleet (node/share.py): real mosquitto, real processes
(tests/runtime/share_proc.py, their robots simulated), their fleet files changed and read again on SIGHUP.

* a robot handed over to a process that drops it (its file no longer lists it) before it takes it, while the
  process that handed it over drops it too, ends `offline` (retired, TD cleared) instead of "online, handed
  over" with nobody serving it; listed again, it is served again;
* a process that claims a robot a moment after another one started claiming it (its ROS graph showed it later)
  leaves it to that one, which hands it over: no stall, no `offline` on the way.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from td2adaptor.runtime.events import now_rfc3339
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.test_fleet_share import INVOKE, Watcher
from tests.runtime.test_fleet_share_discover_ros2 import retained_td_cleared


class Proc:
    """One share_proc process whose robots are those of a file of its own (read again on SIGHUP)."""

    def __init__(self, broker: Mosquitto, tmp: Path, name: str, robots: list[str], **env: str) -> None:
        self.file = tmp / f"{name}.robots"
        self.list(robots)
        self.log_path = tmp / f"{name}.log"
        self._log = open(self.log_path, "w")  # noqa: SIM115 - the child's, closed in close()
        environ = {**os.environ, "SHARE_ROBOTS_FILE": str(self.file), **env}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.runtime.share_proc", broker.url, str(tmp / "state"), "0", str(tmp / "runs")],
            stdout=subprocess.PIPE,
            stderr=self._log,
            text=True,
            env=environ,
        )
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line.startswith("ready"), self.log()
        self.node = line.split()[1]
        self.pid = self.proc.pid

    def list(self, robots: list[str]) -> None:
        self.file.write_text(" ".join(robots) + "\n")

    def reload(self, robots: list[str]) -> None:
        self.list(robots)
        self.proc.send_signal(signal.SIGHUP)

    def log(self) -> str:
        return self.log_path.read_text()[-4000:]

    def close(self) -> int | None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            code = self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = None
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._log.close()
        return code


def status(watcher: Watcher, robot: str) -> dict[str, Any]:
    """The robot's last status payload ({} before any)."""
    last: dict[str, Any] = {}
    for _t, r, payload in watcher.statuses():
        if r == robot:
            last = payload
    return last


def history(watcher: Watcher, robot: str) -> list[tuple[str, int | None, str | None]]:
    """Every status the robot had: (state, owner pid, handed over to)."""
    return [
        (p.get("state", ""), (p.get("owner") or {}).get("pid"), (p.get("handover") or {}).get("node"))
        for _t, r, p in watcher.statuses()
        if r == robot
    ]


def record(watcher: Watcher, node: str) -> dict[str, Any]:
    """The member's last record ({} before any, or once cleared)."""
    last: dict[str, Any] = {}
    for _t, topic, event in watcher.timed():
        if topic == f"td2adaptor/.fleet/shared/members/{node}":
            last = event
    return last


def wait(predicate: Callable[[], bool], timeout: float, *procs: Proc, what: str = "") -> None:
    assert until(predicate, timeout), f"{what}\n" + "\n".join(p.log() for p in procs)


def test_a_robot_handed_over_to_a_process_that_drops_it_while_its_owner_drops_it_too_goes_offline(
    tmp_path: Path,
) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        robots = ["rb_00", "rb_01"]
        a = Proc(broker, tmp_path, "a", robots)
        procs.append(a)
        wait(lambda: all(status(watcher, r).get("state") == "online" for r in robots), 20, a, what="a serves both")
        # x takes what a hands over only 10 s after it starts (SHARE_SETTLE): the window, made wide
        x = Proc(broker, tmp_path, "x", robots, SHARE_SETTLE="10")
        procs.append(x)
        started = time.monotonic()

        def handed() -> str | None:
            return next((r for r in robots if (status(watcher, r).get("handover") or {}).get("node") == x.node), None)

        wait(lambda: handed() is not None, 8, a, x, what="a hands one robot over to x")
        robot = handed()
        assert robot is not None
        other = next(r for r in robots if r != robot)
        # both drop it before x took it: a first (else a, still listing it, takes it back), then x
        a.reload([other])
        wait(lambda: robot not in record(watcher, a.node).get("can", [robot]), 5, a, what="a dropped it")
        x.reload([other])
        wait(lambda: robot not in record(watcher, x.node).get("can", [robot]), 5, x, what="x dropped it")
        assert time.monotonic() - started < 9, "the window closed before both dropped the robot (too slow a machine)"
        assert history(watcher, robot)[-1] == ("online", a.pid, x.node), history(watcher, robot)
        dropped = time.monotonic()
        # a command sent meanwhile waits in the robot's session, whoever connects with it (the retiring too)
        sender = AppClient(broker, ["test/nothing"])
        command = str(uuid.uuid4())
        sender.send(
            INVOKE.format(robot=robot),
            {
                "id": command,
                "time": now_rfc3339(),
                "correlation": command,
                "payload": {"procedure": {"goals": [{"pose": {"x": 7.5, "y": 3.0}}]}},
            },
        )
        sender.close()
        # nobody serves it: its status says so within HANDOVER_WAIT (5 s) and a little, and its TD is gone
        wait(lambda: status(watcher, robot).get("state") == "offline", 8, a, x, what=str(history(watcher, robot)))
        took = time.monotonic() - dropped
        last = status(watcher, robot)
        assert last.get("retired", {}).get("node") == a.node, last
        assert (last.get("owner") or {}).get("pid") == a.pid, last
        assert retained_td_cleared(broker, robot)
        # never online again on the way (no blip of a's re-claim), never served by x
        after = history(watcher, robot)
        assert after[-2:] == [("online", a.pid, x.node), ("offline", a.pid, None)], after
        assert all(pid == a.pid for _s, pid, _h in after), after
        # the robot handed over the other way, or kept, is still served by exactly one of them
        assert status(watcher, other).get("state") == "online", history(watcher, other)
        print(f"retired {took:.2f} s after both dropped it")
        # listed again (by x, which is now past its settle): served again, by x
        x.reload([other, robot])
        wait(lambda: status(watcher, robot).get("state") == "online", 10, a, x, what=str(history(watcher, robot)))
        assert history(watcher, robot)[-1] == ("online", x.pid, None), history(watcher, robot)
        assert until(lambda: not retained_td_cleared(broker, robot), 5)
        # the command sent while nobody served it ran there, once
        wait(lambda: command in watcher.terminals(), 10, a, x, what="the waiting command was answered")
        assert [t.get("state") for t in watcher.terminals()[command]] == ["finished"], watcher.terminals()[command]
        assert "Traceback" not in a.log() + x.log()
    finally:
        codes = [p.close() for p in procs]
        watcher.close()
        broker.stop()
    assert codes == [0] * len(procs), codes
    print(json.dumps({"history": history(watcher, robot)}))


def no_traceback(procs: list[Proc]) -> None:
    for proc in procs:
        assert "Traceback" not in proc.log(), proc.log()


def stop_all(procs: list[Proc], watcher: Watcher) -> list[int | None]:
    """Stop the processes (SIGTERM) and the watcher: the processes' exit codes."""
    codes = [p.close() for p in procs]
    watcher.close()
    return codes


def hand_one_over_slowly(
    broker: Mosquitto, tmp_path: Path, watcher: Watcher, procs: list[Proc]
) -> tuple[Proc, Proc, str, str, float]:
    """a serves rb_00 and rb_01; x joins and takes what it is handed only 10 s later (SHARE_SETTLE): a hands one
    over to x. (a, x, the robot handed over, the other one, when x had joined: time.monotonic())"""
    robots = ["rb_00", "rb_01"]
    a = Proc(broker, tmp_path, "a", robots)
    procs.append(a)
    wait(lambda: all(status(watcher, r).get("state") == "online" for r in robots), 20, a, what="a serves both")
    x = Proc(broker, tmp_path, "x", robots, SHARE_SETTLE="10")  # takes what it is handed only 10 s later
    procs.append(x)
    joined = time.monotonic()

    def handed() -> str | None:
        return next((r for r in robots if (status(watcher, r).get("handover") or {}).get("node") == x.node), None)

    wait(lambda: handed() is not None, 8, a, x, what="a hands one robot over to x")
    robot = handed()
    assert robot is not None
    return a, x, robot, next(r for r in robots if r != robot), joined


def test_a_robot_handed_over_by_a_process_that_died_before_it_retired_it_is_retired_by_a_survivor(
    tmp_path: Path,
) -> None:
    """a hands a robot over to x, which takes it only later (SHARE_SETTLE); a drops it and is killed (kill -9)
    before it could retire it, then x drops it too: nobody lists it, and its status says "online, handed over"
    by a dead process. x, the member it was handed over to, retires it with the fleet's settings."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        a, x, robot, other, started = hand_one_over_slowly(broker, tmp_path, watcher, procs)
        a.reload([other])
        wait(lambda: robot not in record(watcher, a.node).get("can", [robot]), 5, a, what="a dropped it")
        a.proc.kill()  # before it retired it (it would, 2 s after x dropped it too)
        a.proc.wait(10)
        wait(lambda: "owner" not in record(watcher, a.node), 5, a, what="a's record cleared by its will")
        x.reload([other])
        wait(lambda: robot not in record(watcher, x.node).get("can", [robot]), 5, x, what="x dropped it")
        assert time.monotonic() - started < 9, "the window closed before x dropped the robot (too slow a machine)"
        assert history(watcher, robot)[-1] == ("online", a.pid, x.node), history(watcher, robot)
        dropped = time.monotonic()
        wait(lambda: status(watcher, robot).get("state") == "offline", 15, x, what=str(history(watcher, robot)))
        took = time.monotonic() - dropped
        last = status(watcher, robot)
        assert last.get("retired", {}).get("node") == x.node, last
        assert (last.get("owner") or {}).get("pid") == x.pid, last
        assert retained_td_cleared(broker, robot)
        assert history(watcher, robot)[-2:] == [("online", a.pid, x.node), ("offline", x.pid, None)]
        assert status(watcher, other).get("state") == "online", history(watcher, other)
        print(f"retired {took:.2f} s after the last member dropped it")
        # listed again: served again, by x
        x.reload([other, robot])
        wait(lambda: status(watcher, robot).get("state") == "online", 15, x, what=str(history(watcher, robot)))
        assert history(watcher, robot)[-1] == ("online", x.pid, None), history(watcher, robot)
        assert "Traceback" not in x.log()
    finally:
        codes = [p.close() for p in procs]
        watcher.close()
        broker.stop()
    assert codes[1:] == [0], codes


def test_a_robot_whose_hand_over_both_members_died_in_is_retired_by_a_member_that_joined_later(
    tmp_path: Path,
) -> None:
    """As above, but x is killed too before it retired the robot, and the only survivor, s, joined after both had
    left: it never saw their records, so it did not know that the process whose hand-over the status names left
    the fleet, and left the robot "online, handed over" for ever. That process was of this host and runs no
    more: s retires the robot."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        a, x, robot, other, _started = hand_one_over_slowly(broker, tmp_path, watcher, procs)
        # a let it go (its connection closed cleanly, no will), x takes what it is handed only 10 s after it joined
        wait(lambda: robot not in record(watcher, a.node).get("robots", [robot]), 10, a, what="a let it go")
        for proc in (a, x):  # both die before the robot was taken or retired
            proc.proc.kill()
            proc.proc.wait(10)
            gone = proc.node
            wait(lambda: "owner" not in record(watcher, gone), 5, proc, what="its record cleared by its will")  # noqa: B023
        assert history(watcher, robot)[-1] == ("online", a.pid, x.node), history(watcher, robot)
        s = Proc(broker, tmp_path, "s", [other])  # joins now: it never saw a or x
        procs.append(s)
        joined = time.monotonic()
        wait(lambda: status(watcher, robot).get("state") == "offline", 15, s, what=str(history(watcher, robot)))
        took = time.monotonic() - joined
        last = status(watcher, robot)
        assert last.get("retired", {}).get("node") == s.node, last
        assert retained_td_cleared(broker, robot)
        assert history(watcher, robot)[-2:] == [("online", a.pid, x.node), ("offline", s.pid, None)]
        wait(lambda: status(watcher, other).get("state") == "online", 15, s, what=str(history(watcher, other)))
        assert (status(watcher, other).get("owner") or {}).get("pid") == s.pid
        print(f"retired {took:.2f} s after s joined")
        assert "Traceback" not in s.log()
    finally:
        codes = [p.close() for p in procs]
        watcher.close()
        broker.stop()
    assert codes[2:] == [0], codes


def test_a_process_that_claims_a_robot_another_one_is_claiming_leaves_it_to_that_one(tmp_path: Path) -> None:
    """l starts claiming its four robots, whose ROS side takes 3 s to come up; w lists them meanwhile (more than
    SETTLE after l) and gets two of them by the plan. Once, w found them free (l was not online yet) and claimed
    them; l then connected as well and took their sessions from w: w's reconnection took them back, found them
    l's and went off (`offline`), l's went off in turn, and each robot was `online` by w, by l, `offline`, then
    `online` again. Then l looked once more right before it connected and left w's robots to w, its own start of
    them thrown away. Now w leaves them to l while l's record says it is `starting` them (test_fleet_share_
    starting.py): l serves all four at the end of its start and hands two over to w, each robot `online`
    throughout, one session at a time."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    watcher = Watcher(broker)
    procs: list[Proc] = []
    robots = [f"rb_{i:02d}" for i in range(4)]
    try:
        w = Proc(broker, tmp_path, "w", [])
        procs.append(w)
        late = Proc(broker, tmp_path, "l", robots, SHARE_GROW_DELAY="3")
        procs.append(late)
        pids = {w.pid, late.pid}
        wait(lambda: bool(record(watcher, late.node).get("can")), 10, late, what="l joined")
        time.sleep(1.5)  # l is inside its claim (it starts 1 s after it joined, and lasts 3 s)
        w.reload(robots)
        seen = time.monotonic()

        def settled() -> bool:
            last = {r: status(watcher, r) for r in robots}
            if not all(p.get("state") == "online" and not p.get("handover") for p in last.values()):
                return False
            served = {r: p.pid for p in procs for r in record(watcher, p.node).get("robots", [])}
            owners = {r: (last[r].get("owner") or {}).get("pid") for r in robots}
            return sorted(served) == robots and owners == served and set(owners.values()) == pids

        wait(settled, 20, w, late, what=str({r: history(watcher, r) for r in robots}))
        took = time.monotonic() - seen
        hist = {r: history(watcher, r) for r in robots}
        print(f"settled {took:.2f} s after w listed them", json.dumps(hist))
        assert {(status(watcher, r).get("owner") or {}).get("pid") for r in robots} == pids, hist
        for robot, seq in hist.items():
            assert all(state == "online" for state, _pid, _to in seq), (robot, seq)  # never offline on the way
            for (_s, before, to), (_s2, after, _t2) in zip(seq, seq[1:], strict=False):
                assert before == after or to is not None, (robot, seq)  # another owner only by hand-over
        assert took < 8, took  # no stall
        logs = w.log() + late.log()
        assert "Traceback" not in logs and "SUBACK" not in logs and "took its session over" not in logs, logs
    finally:
        codes = [p.close() for p in procs]
        watcher.close()
        broker.stop()
    assert codes == [0, 0], codes


def test_a_hand_over_status_counts_the_goals_in_flight(broker: Mosquitto, tmp_path: Path) -> None:
    """A robot handed over with a ROS action goal in flight (the next owner follows it on) said `online,
    missions: 0` in its hand-over status until the next owner's first status (a new user's lift fleet: 0.5-0.9 s
    of 0 during a rebalance, as `fleet status` and a dashboard show it). The next owner's first status is
    test_goal_rejoin.py's: here each process simulates its own action servers, so b cannot follow a's goals."""
    watcher = Watcher(broker)
    sender = AppClient(broker, ["test/nothing"])
    robots = ["rb_00", "rb_01"]
    procs: list[Proc] = []
    try:
        a = Proc(broker, tmp_path, "a", robots, SHARE_ACTIONS="1")
        procs.append(a)
        wait(lambda: all(history(watcher, r)[-1:] == [("online", a.pid, None)] for r in robots), 30, a)
        for robot in robots:  # 400 steps of 0.05 s: still running when the robot moves
            event = {"id": uuid.uuid4().hex, "time": now_rfc3339(), "payload": {"order": 400}}
            sender.send(f"td2adaptor/{robot}/MathComponent/fibonacci", event)
        running = lambda: {t.split("/")[1] for _w, t, e in watcher.timed() if t.endswith("/fibonacci/feedback")}  # noqa: E731
        wait(lambda: running() == set(robots), 30, a, what="goals running")
        b = Proc(broker, tmp_path, "b", robots, SHARE_ACTIONS="1")
        procs.append(b)
        wait(lambda: any(history(watcher, r)[-1][1] == b.pid for r in robots), 30, a, b, what="one robot moved to b")
        (moved,) = [r for r in robots if history(watcher, r)[-1][1] == b.pid]
        seen = [p for _t, r, p in watcher.statuses() if r == moved]
        handover = [p for p in seen if p.get("handover")]
        assert handover and all(p["missions"] == 1 for p in handover), handover
        no_traceback(procs)
    finally:
        sender.close()
        stop_all(procs, watcher)
