"""What the terminal event of a mission in flight says when its process is killed and another member of the fleet
takes the robot over (node/share.py, docs/fleet.md "Several processes share a fleet"): real mosquitto, real
processes (tests/runtime/share_proc.py with `SHARE_ACTIONS`: the robots' action is a ROS action, simulated).

A ROS action goal an earlier owner sent is followed on by the new owner by its id (test_goal_rejoin_ros2.py, on a
real ROS 2 server); here each process has simulated action servers of its own, so the new owner's server does not
know the goal (as after a robot's restart): it ends `failed` with `reason: unreachable`. Its words said "the edge
node restarted", which nothing had: another process took the robot over after its owner was lost. They say that
now, naming both processes, and why the goal could not be followed on; the codes stay.
"""

from __future__ import annotations

import re
import uuid
from pathlib import Path

import pytest

from td2adaptor.runtime.events import now_rfc3339
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.test_fleet_share import Procs, Watcher, served_by, shares

GOAL = "td2adaptor/{robot}/MathComponent/fibonacci"
DOC = (Path(__file__).parents[2] / "docs" / "fleet.md").read_text(encoding="utf-8")
LONG = 400  # the goal's order: 400 feedback steps of 0.05 s, 20 s (SimActions), in flight at the kill


def test_a_goal_in_flight_on_a_killed_process_ends_saying_another_process_took_the_robot_over(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SHARE_ACTIONS", "1")
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    procs = Procs(broker, tmp_path, 2)
    watcher = Watcher(broker)
    sender = AppClient(broker, ["test/nothing"])
    try:
        started = procs.start_many(2)
        pids = {p.pid for p in started}
        assert until(lambda: served_by(watcher, pids, 2) and set(shares(watcher, pids).values()) == {1}, 60)
        victim, survivor = started
        robot = next(r for r, (_s, pid) in watcher.owners().items() if pid == victim.pid)
        event_id = uuid.uuid4().hex
        event = {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": {"order": LONG}}
        sender.send(GOAL.format(robot=robot), event)

        def running() -> bool:  # the goal's feedback came: it is in flight on the victim
            return any(
                e.get("type") == "feedback" and e.get("correlation") == event_id and e["payload"].get("seq", 0) >= 2
                for _t, _topic, e in watcher.timed()
            )

        assert until(running, 20), procs.logs()
        victim.kill()
        victim.wait()
        assert until(lambda: event_id in watcher.terminals(), 20), procs.logs()
        ends = watcher.terminals()[event_id]
        assert len(ends) == 1, ends
        end = ends[0]
        assert (end["state"], end.get("reason")) == ("failed", "unreachable"), end  # the documented codes
        words = end.get("message", "")
        print(words)
        assert "restarted" not in words, words
        assert words.startswith(f"another process of fleet shared, process {survivor.pid} on "), words
        assert f"took the robot over after its edge node, process {victim.pid} on " in words, words
        assert "), was lost while it followed this goal (" in words and "its outcome is unknown" in words, words
        assert "), and following it on failed: the action server does not know goal " in words, words
        assert watcher.owners()[robot] == ("online", survivor.pid)
        # docs/fleet.md quotes these words: its placeholders match what was said
        quoted = re.search(r'"(another process of fleet F, .*?: its outcome is unknown)"', " ".join(DOC.split()))
        assert quoted is not None, "docs/fleet.md quotes the words of a takeover"
        pattern = re.escape(quoted.group(1))
        for placeholder in ("F", "Q", "P", "H"):
            pattern = re.sub(rf"\b{placeholder}\b", r"\\S+", pattern)
        assert re.match(pattern.replace(re.escape("..."), ".*?"), words), (quoted.group(1), words)
    finally:
        sender.close()
        watcher.close()
        procs.close()
        broker.stop()
