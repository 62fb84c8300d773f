"""A robot whose owner changes while a member starts it, in a shared fleet (node/share.py): real mosquitto, real
processes (tests/runtime/share_proc.py, their robots simulated; `SHARE_GROW_DELAY` makes each start slow, as a
loaded machine's ROS side is).

Issue 32's scenario at 30 robots: a member started robots that another member listed a moment later (its ROS graph
showed them later); the plan changed during the start, the last look before serving declined them and their new
owner started them from scratch, seconds late. Now the new owner leaves a robot alone while a member's record says
it is `starting` it; that member serves it at the end of its start and hands it over then.
"""

from __future__ import annotations

import time
from pathlib import Path

from tests.runtime.broker import Mosquitto
from tests.runtime.test_fleet_share import Watcher
from tests.runtime.test_fleet_share_handover import Proc, history, no_traceback, stop_all, wait

START = 4.0  # seconds each member's start of its robots takes (SHARE_GROW_DELAY)


def first_online(watcher: Watcher, robot: str) -> tuple[float, int | None]:
    """When `robot` first went online, and by which process (its pid); (inf, None) before."""
    for t, r, p in watcher.statuses():
        if r == robot and p.get("state") == "online":
            return t, (p.get("owner") or {}).get("pid")
    return float("inf"), None


def test_a_robot_listed_by_another_member_during_its_start_is_served_at_its_end_and_handed_over_not_started_again(
    broker: Mosquitto, tmp_path: Path
) -> None:
    robots = ["rb_00", "rb_01"]
    watcher = Watcher(broker)
    procs: list[Proc] = []
    try:
        b = Proc(broker, tmp_path, "b", [], SHARE_SETTLE="0.1", SHARE_GROW_DELAY=str(START))
        procs.append(b)
        a = Proc(broker, tmp_path, "a", robots, SHARE_SETTLE="0.1", SHARE_GROW_DELAY=str(START))
        procs.append(a)
        wait(lambda: "starting rb_00 rb_01" in a.log(), 15, a, what="a starts both robots")
        # b lists them half-way through a's start (its graph showed them later), not as an event a or b waits for:
        # the plan gives one of them to b, which started it from scratch then (online START / 2 + SETTLE after a's)
        time.sleep(START / 2)
        b.reload(robots)
        began = time.monotonic()
        moved = None

        def settled() -> bool:
            nonlocal moved
            last = {r: history(watcher, r)[-1:] for r in robots}
            mine = [r for r in robots if last[r] and last[r][0][:2] == ("online", b.pid) and last[r][0][2] is None]
            moved = mine[0] if len(mine) == 1 else None
            return moved is not None and all(last[r] and last[r][0][0] == "online" for r in robots)

        wait(settled, 30, a, b, what="one robot ends with b")
        assert moved is not None
        kept = next(r for r in robots if r != moved)
        at_kept, by_kept = first_online(watcher, kept)
        at_moved, by_moved = first_online(watcher, moved)
        print(
            f"b listed them {time.monotonic() - began:.1f} s ago; online: {kept} by a at +0, {moved} at "
            f"{at_moved - at_kept:+.2f} s, then handed over to b"
        )
        assert by_kept == a.pid
        # a's start was not thrown away: the robot the plan moved to b during it came online with the other one, by
        # a, and went to b by hand-over (online throughout), not started by b from scratch after a declined it
        assert by_moved == a.pid, (history(watcher, moved), a.log(), b.log())
        assert at_moved - at_kept <= 1.0, history(watcher, moved)
        assert history(watcher, moved) == [("online", a.pid, None), ("online", a.pid, b.node), ("online", b.pid, None)]
        assert history(watcher, kept) == [("online", a.pid, None)]
        no_traceback(procs)
    finally:
        codes = stop_all(procs, watcher)
    assert codes == [0, 0]
