"""A shared fleet's member says what its discovery sees while it starts other robots (node/share.py, node/fleet.py):
real mosquitto, a real process (tests/runtime/share_proc.py, its robots simulated, `SHARE_GROW_DELAY` making each
start slow, as a loaded machine's ROS side is, its "graph" a file).

Issue 32: robots added to a shared fleet are served within 2 s. A member's record (its `found`: what its discovery
sees) is what the other members wait for before a robot newly seen is given out (`_heard`). Reading which robots
the fleet serves took the fleet's lock, which a start holds: a member starting some robots told the others of one
its graph showed meanwhile only once that start had ended, and its discovery looked no more until then.
"""

from __future__ import annotations

import time
from pathlib import Path

from tests.runtime.broker import Mosquitto
from tests.runtime.test_fleet_share import Watcher
from tests.runtime.test_fleet_share_handover import Proc, wait

START = 6.0  # seconds the member's start of its robots takes (SHARE_GROW_DELAY)


def found_at(watcher: Watcher, node: str, robot: str) -> float:
    """When member `node`'s record first said its discovery sees `robot` (inf before)."""
    for t, topic, record in watcher.timed():
        if topic.endswith(f"/members/{node}") and robot in (record.get("found") or ()):
            return t
    return float("inf")


def online_at(watcher: Watcher, robot: str) -> float:
    for t, r, payload in watcher.statuses():
        if r == robot and payload.get("state") == "online":
            return t
    return float("inf")


def test_a_member_says_what_its_graph_shows_while_it_starts_other_robots(broker: Mosquitto, tmp_path: Path) -> None:
    graph = tmp_path / "a.graph"
    graph.write_text("rs_x\n")
    watcher = Watcher(broker)
    a = None
    try:
        slow = {"SHARE_SETTLE": "0.1", "SHARE_GROW_DELAY": str(START)}
        a = Proc(broker, tmp_path, "a", [], SHARE_FOUND_FILE=str(graph), **slow)
        wait(lambda: "starting rs_x" in a.log(), 20, a, what="a starts rs_x")
        shown = time.monotonic()
        graph.write_text("rs_x rs_y\n")  # its graph shows another robot during that start
        wait(lambda: online_at(watcher, "rs_x") < float("inf"), 30, a, what="rs_x online")
        wait(lambda: found_at(watcher, a.node, "rs_y") < float("inf"), 30, a, what="rs_y in a's record")
        said, started = found_at(watcher, a.node, "rs_y"), online_at(watcher, "rs_x")
        print(f"rs_y in a's record {said - shown:.2f} s after its graph showed it; rs_x online {started - shown:.2f} s")
        # before: once the start of rs_x had ended (about START after), with rs_x's `online`
        assert said < started, (said - shown, started - shown)
        assert said - shown < START / 2, said - shown
        assert "Traceback" not in a.log(), a.log()
    finally:
        code = a.close() if a is not None else 0
        watcher.close()
    assert code == 0
