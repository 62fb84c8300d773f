"""A shared fleet's member starts a set of robots while another set's start is under way (node/share.py `_begin`,
node/fleet.py `Fleet.join`): real mosquitto, real processes (tests/runtime/share_proc.py, their robots simulated;
`SHARE_GROW_DELAY` with `SHARE_SLOW` makes one robot's start slow, as a loaded machine's ROS side is, the others
come up at once; a member's "graph" is a file).

Issue 32: robots added to a shared fleet are served within 2 s. A process started one set of robots at a time: a
robot it claimed during the start of others waited for that start's end (0.2-1 s at load 18-36), and so did a
hand-over of a robot it served. Each robot is still started once, and the robot whose start is under way is
served at its end.
"""

from __future__ import annotations

import time
from pathlib import Path

from tests.runtime.broker import Mosquitto
from tests.runtime.test_fleet_share import Watcher
from tests.runtime.test_fleet_share_handover import Proc, history, no_traceback, stop_all, wait

START = 8.0  # seconds the slow robot's start takes (SHARE_GROW_DELAY)


def online_at(watcher: Watcher, robot: str, pid: int) -> float:
    """When `robot` first went online served by process `pid` (inf before)."""
    for t, r, p in watcher.statuses():
        if r == robot and p.get("state") == "online" and (p.get("owner") or {}).get("pid") == pid:
            return t
    return float("inf")


def test_a_robot_found_during_the_slow_start_of_another_is_served_before_that_start_ends_and_each_starts_once(
    broker: Mosquitto, tmp_path: Path
) -> None:
    graph = tmp_path / "a.graph"
    graph.write_text("rs_x\n")
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        slow = {"SHARE_SETTLE": "0.1", "SHARE_GROW_DELAY": str(START), "SHARE_SLOW": "rs_x"}
        a = Proc(broker, tmp_path, "a", [], SHARE_FOUND_FILE=str(graph), **slow)
        procs.append(a)
        wait(lambda: "starting rs_x" in a.log(), 20, a, what="a starts rs_x")
        shown = time.monotonic()
        graph.write_text("rs_x rs_y\n")  # its graph shows another robot during that start
        wait(lambda: online_at(watcher, "rs_x", a.pid) < float("inf"), 40, a, what="rs_x online")
        wait(lambda: online_at(watcher, "rs_y", a.pid) < float("inf"), 30, a, what="rs_y online")
        x, y = online_at(watcher, "rs_x", a.pid), online_at(watcher, "rs_y", a.pid)
        print(f"rs_y online {y - shown:.2f} s after the graph showed it; rs_x {x - shown:.2f} s")
        # before: rs_y was claimed only once the start of rs_x had ended (about START after), and came online after it
        assert y < x, (y - shown, x - shown, a.log())
        assert y - shown < START / 2, (y - shown, a.log())
        # rounds of the share ran during the start of rs_x (rs_y's claim, its start's end): none started it again
        log = a.log_path.read_text()
        assert log.count("starting rs_x") == 1, log
        assert log.count("starting rs_y") == 1, log
        assert history(watcher, "rs_x") == [("online", a.pid, None)]
        assert history(watcher, "rs_y") == [("online", a.pid, None)]
        no_traceback(procs)
    finally:
        codes = stop_all(procs, watcher)
    assert codes == [0]


def test_a_robot_is_handed_over_during_the_slow_start_of_another_which_is_served_at_its_end(
    broker: Mosquitto, tmp_path: Path
) -> None:
    robots = ["rb_00", "rb_01"]
    graph = tmp_path / "a.graph"
    graph.write_text("\n")
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        slow = {"SHARE_SETTLE": "0.1", "SHARE_GROW_DELAY": str(START), "SHARE_SLOW": "rs_x"}
        a = Proc(broker, tmp_path, "a", robots, SHARE_FOUND_FILE=str(graph), **slow)
        procs.append(a)
        b = Proc(broker, tmp_path, "b", [], SHARE_SETTLE="0.1")  # a member that lists nothing yet
        procs.append(b)
        wait(lambda: all(history(watcher, r) == [("online", a.pid, None)] for r in robots), 20, a, what="a serves")
        graph.write_text("rs_x\n")  # a's graph shows a robot whose start is slow
        wait(lambda: "starting rs_x" in a.log(), 20, a, what="a starts rs_x")
        b.reload(robots)  # b lists the robots a serves during that start: the plan gives it one or both
        listed = time.monotonic()

        def moved() -> list[str]:
            return [r for r in robots if online_at(watcher, r, b.pid) < float("inf")]

        wait(lambda: bool(moved()), 40, a, b, what="a robot handed over to b")
        wait(lambda: online_at(watcher, "rs_x", a.pid) < float("inf"), 40, a, what="rs_x online")
        x = online_at(watcher, "rs_x", a.pid)
        over = {r: online_at(watcher, r, b.pid) for r in moved()}
        print(f"b listed them; handed over: {', '.join(f'{r} +{t - listed:.2f} s' for r, t in over.items())}")
        print(f"rs_x online +{x - listed:.2f} s")
        # before: a handed a robot over only once its start of rs_x had ended
        for robot, t in over.items():
            assert t < x, (robot, t - listed, x - listed, a.log(), b.log())
            # online throughout: by a, by a handed over to b, by b
            handed = [("online", a.pid, None), ("online", a.pid, b.node), ("online", b.pid, None)]
            assert history(watcher, robot) == handed
        # the robot whose start was under way is served by a at its end, started once
        assert history(watcher, "rs_x") == [("online", a.pid, None)]
        assert a.log_path.read_text().count("starting rs_x") == 1, a.log()
        no_traceback(procs)
    finally:
        codes = stop_all(procs, watcher)
    assert codes == [0, 0]


def test_a_robot_claimed_in_the_round_that_retires_another_starts_before_that_ones_slow_stop_ended(
    broker: Mosquitto, tmp_path: Path
) -> None:
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        slow = {"SHARE_SETTLE": "0.1", "SHARE_NEW_SETTLE": "0", "SHARE_CLOSE_DELAY": str(START)}
        a = Proc(broker, tmp_path, "a", ["rb_00"], SHARE_SLOW_CLOSE="rb_00", **slow)
        procs.append(a)
        wait(lambda: history(watcher, "rb_00") == [("online", a.pid, None)], 20, a, what="a serves rb_00")
        a.reload(["rs_y"])  # one round: rb_00 retired (its port takes START to close), rs_y claimed
        began = time.monotonic()
        wait(lambda: online_at(watcher, "rs_y", a.pid) < float("inf"), 30, a, what="rs_y online")
        y = online_at(watcher, "rs_y", a.pid) - began
        wait(lambda: "rb_00: no longer served" in a.log(), 30, a, what="rb_00 stopped")
        stopped = time.monotonic() - began
        print(f"rs_y online {y:.2f} s after the reload; rb_00's stop ended {stopped:.2f} s after it")
        # before: the round claimed rs_y only once rb_00's stop had ended, and its start took the fleet's lock, which
        # that stop held
        assert y < START / 2, (y, a.log())
        assert [s for s, _pid, _to in history(watcher, "rb_00")] == ["online", "offline"]
        assert history(watcher, "rs_y") == [("online", a.pid, None)]
        no_traceback(procs)
    finally:
        codes = stop_all(procs, watcher)
    assert codes == [0]


def test_a_robot_found_while_another_is_retired_slowly_is_served_before_that_ones_stop_ended(
    broker: Mosquitto, tmp_path: Path
) -> None:
    graph = tmp_path / "a.graph"
    graph.write_text("\n")
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        slow = {"SHARE_SETTLE": "0.1", "SHARE_NEW_SETTLE": "0", "SHARE_CLOSE_DELAY": str(START)}
        a = Proc(broker, tmp_path, "a", ["rb_00"], SHARE_FOUND_FILE=str(graph), SHARE_SLOW_CLOSE="rb_00", **slow)
        procs.append(a)
        wait(lambda: history(watcher, "rb_00") == [("online", a.pid, None)], 20, a, what="a serves rb_00")
        a.reload([])  # rb_00 is retired: its port takes START to close
        wait(lambda: [s for s, _pid, _to in history(watcher, "rb_00")] == ["online", "offline"], 20, a, what="retired")
        graph.write_text("rs_y\n")  # its graph shows a robot during that stop
        shown = time.monotonic()
        wait(lambda: online_at(watcher, "rs_y", a.pid) < float("inf"), 30, a, what="rs_y online")
        y = online_at(watcher, "rs_y", a.pid) - shown
        wait(lambda: "rb_00: no longer served" in a.log(), 30, a, what="rb_00 stopped")
        stopped = time.monotonic() - shown
        print(f"rs_y online {y:.2f} s after the graph showed it; rb_00's stop ended {stopped:.2f} s after it")
        # before: the round that retired rb_00 stopped it, and the next round, which claims rs_y, came only after
        assert y < START / 2, (y, a.log())
        assert history(watcher, "rs_y") == [("online", a.pid, None)]
        no_traceback(procs)
    finally:
        codes = stop_all(procs, watcher)
    assert codes == [0]
