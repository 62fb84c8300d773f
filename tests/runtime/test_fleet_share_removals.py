"""A robot removed from a shared fleet (node/share.py `_hold`): real mosquitto, real processes
(tests/runtime/share_proc.py, their robots simulated, each one's fleet file read again on SIGHUP).

The members stop listing a removed robot each at its own moment (they read the file, the admin's entry or their
ROS graph a little apart). Each removal changed the bounded plan at once, so an unrelated robot could go from one
member to the other at the first and back at the second (a new user's trial of issue 32: 80 ms apart, four
statuses and two MQTT sessions for nothing). A removal now settles like an addition: the plan changes once.
"""

from __future__ import annotations

import time
from pathlib import Path

from td2adaptor.runtime.node.shareplan import assign
from tests.runtime.broker import Mosquitto
from tests.runtime.test_fleet_share import Watcher
from tests.runtime.test_fleet_share_handover import Proc, history, no_traceback, stop_all, wait

SETTLE = 2.0  # share.SETTLE in the processes (0.75 s by default): room for a loaded machine between the two reads
APART = 0.3  # seconds between the two members' reads of the changed fleet


def ping_pong(c: str, d: str) -> tuple[list[str], str, str]:
    """Robots, one of them to remove and another one, unrelated, that the plan moves between members `c` and `d`
    when `c` stops listing the first one, and moves back when `d` stops too (the plans depend on the node ids)."""
    for prefix in ("rb", "ro", "ra", "rc", "rd"):
        for n in range(3, 9):
            robots = [f"{prefix}_{i:02d}" for i in range(n)]
            every = {c: set(robots), d: set(robots)}
            before = assign(robots, {c, d}, every)
            for gone in robots:
                left = set(robots) - {gone}
                between = assign(robots, {c, d}, {c: left, d: set(robots)})
                after = assign(left, {c, d}, {c: left, d: left})
                moved = [r for r in sorted(left) if before[r] == after[r] != between[r]]
                if moved:
                    return robots, gone, moved[0]
    raise AssertionError(f"no robots whose plan moves back and forth for members {c} and {d}")


def test_a_robot_the_members_stop_listing_a_moment_apart_moves_no_other_robot_back_and_forth(
    broker: Mosquitto, tmp_path: Path
) -> None:
    watcher = Watcher(broker)
    env = {"SHARE_SETTLE": "0.1", "SHARE_NEW_SETTLE": str(SETTLE)}
    procs: list[Proc] = []
    try:
        c = Proc(broker, tmp_path, "c", [], **env)
        procs.append(c)
        d = Proc(broker, tmp_path, "d", [], **env)
        procs.append(d)
        robots, gone, other = ping_pong(c.node, d.node)
        plan = assign(robots, {c.node, d.node})
        pid = {c.node: c.pid, d.node: d.pid}
        c.reload(robots)
        d.reload(robots)
        wait(
            lambda: all(history(watcher, r)[-1:] == [("online", pid[plan[r]], None)] for r in robots),
            30,
            c,
            d,
            what="every robot served by its member",
        )
        served = {r: len(history(watcher, r)) for r in robots}

        c.reload([r for r in robots if r != gone])  # c reads the changed fleet first, d a moment later
        time.sleep(APART)
        d.reload([r for r in robots if r != gone])
        wait(lambda: history(watcher, gone)[-1][0] == "offline", 30, c, d, what=f"{gone} retired")
        time.sleep(SETTLE + 1)  # the removal settled: nothing moves after that either
        print(f"{gone} removed; {other}: {history(watcher, other)[served[other] - 1 :]}")
        assert history(watcher, other)[served[other] - 1 :] == [("online", pid[plan[other]], None)], (
            c.log(),
            d.log(),
        )
        for robot in set(robots) - {gone}:
            assert len(history(watcher, robot)) == served[robot], (robot, history(watcher, robot))
        no_traceback(procs)
    finally:
        codes = stop_all(procs, watcher)
    assert codes == [0, 0]


def test_a_reload_that_lists_a_new_robot_says_so_where_it_said_no_change(broker: Mosquitto, tmp_path: Path) -> None:
    """In a shared fleet a robot the reloaded file lists is given out a moment later (the settling), not by the
    reload itself, so `run` logged "fleet file fleet.yaml reloaded (SIGHUP): no change" for a file that had just
    gained a robot (a new user's lift fleet: lift7 was served 0.8 s later). The reload now says what it listed."""
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        a = Proc(broker, tmp_path, "a", [])
        procs.append(a)
        b = Proc(broker, tmp_path, "b", [])
        procs.append(b)
        a.reload(["rb_new"])
        b.reload(["rb_new"])
        wait(lambda: (history(watcher, "rb_new")[-1:] or [("",)])[0][0] == "online", 30, a, b, what="rb_new served")
        for proc in (a, b):
            wait(lambda: "reloaded: rb_new:" in proc.log(), 10, proc, what="the reload logged")  # noqa: B023
            line = next(x for x in proc.log().splitlines() if "reloaded: rb_new:" in x)
            assert "no change" not in line and ("lists rb_new now" in line or "added rb_new" in line), line
        assert any("lists rb_new now" in proc.log() for proc in (a, b))  # given out after the reload
        no_traceback(procs)
    finally:
        stop_all(procs, watcher)
