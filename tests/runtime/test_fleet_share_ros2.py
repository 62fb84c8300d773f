"""Two `td2adaptor run --share` processes share one fleet file's robots (issue 32, node/share.py), for real: the
simulated RB-1s in a ROS 2 process of their own, a real mosquitto, a real kill -9.

The killed process's robots are served again by the other within 5 s; the mission it was following goes on,
because the new owner finds it in the robot's ledger (the processes share the state directory) and the ROS robot
is the same: it follows it to its end, and the application gets one terminal event. The invoke sent again
under its id is answered, not run. `fleet status` shows the member and its takeovers; a process started again
takes its share back by hand-over, without a robot going offline.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
import uuid
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from td2adaptor.runtime.events import now_rfc3339
from tests.ros2.common import Process
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import RunProcess, feedback, until
from tests.runtime.rb1 import GOAL, terminal
from tests.runtime.test_fleet_changes_ros2 import Watch, answering, goto, node_env, run_args, sim_process

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

NAMESPACES = ("sh_a", "sh_b", "sh_c", "sh_d")
ROBOTS = {f"share_{ns[-1]}": ns for ns in NAMESPACES}


@pytest.fixture(scope="module")
def robots(rb1_prefix: Path) -> Iterator[Process]:
    process = sim_process(rb1_prefix, NAMESPACES)
    yield process
    process.stop()


def owners(watch: Watch) -> dict[str, tuple[str, int | None]]:
    out: dict[str, tuple[str, int | None]] = {}
    for t, e in list(watch.app.events):
        parts = t.split("/")
        if len(parts) == 3 and parts[2] == "status" and parts[1] in ROBOTS:
            p = e["payload"]
            out[parts[1]] = (p["state"], (p.get("owner") or {}).get("pid"))
    return out


def shares(watch: Watch) -> Counter[int | None]:
    return Counter(pid for state, pid in owners(watch).values() if state == "online")


def test_run_share_takes_a_killed_processs_robots_over_and_its_mission_goes_on(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.yaml"
    lines = [f"bus: {broker.url}", "poll_period: 0.1", "property_period: 0", f"state_dir: {tmp_path / 'state'}"]
    lines += ["fleet: share_test", "robots:", *(f"  - {{robot: {r}, namespace: {ns}}}" for r, ns in ROBOTS.items())]
    fleet.write_text("\n".join(lines) + "\n", encoding="utf-8")
    watch = Watch(broker, "share-app")
    environ = node_env(rb1_prefix, adaptor_build)
    runs = [RunProcess(run_args("--config", str(fleet), "--share"), env=environ) for _ in range(2)]
    try:
        for run in runs:
            run.wait_ready()
        pids = {r.proc.pid for r in runs}
        assert until(lambda: set(shares(watch)) == pids and set(shares(watch).values()) == {2}, 60), owners(watch)
        victim, other = runs
        theirs = sorted(r for r, (_s, pid) in owners(watch).items() if pid == victim.proc.pid)
        event_id = uuid.uuid4().hex
        invoke = {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": GOAL}
        answering(watch, theirs[0])  # the new edge node's first call to the robot may go unanswered (ROS 2)
        watch.app.send(goto(theirs[0]), invoke)
        watch.app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, event_id)], timeout=20)

        killed = time.monotonic()
        victim.proc.kill()
        victim.proc.wait()
        assert until(lambda: set(shares(watch)) == {other.proc.pid} and sum(shares(watch).values()) == 4, 20), (
            owners(watch),
            other.output()[-3000:],
        )
        took = max((watch.status_at(r, "online", killed) or 1e9) - killed for r in theirs)
        print(f"kill -9 -> the other process serves its robots: {took:.2f} s")
        assert took <= 5.0
        # the mission in flight goes on with the new owner: one terminal event, `finished`
        watch.app.wait(terminal("feedback", event_id), timeout=30)
        ends = [e["payload"] for e in feedback(watch.app.events, event_id) if e["payload"].get("terminal")]
        assert [p["state"] for p in ends] == ["finished"], ends
        seqs = [e["payload"]["seq"] for e in feedback(watch.app.events, event_id)]
        # sent again under its id: answered with its last feedback event again, not run
        watch.app.send(goto(theirs[0]), invoke)
        watch.app.wait(lambda ev: len(feedback(ev, event_id)) > len(seqs), timeout=20)
        time.sleep(1.0)  # a run would have sent `queued` by now
        again = [e["payload"] for e in feedback(watch.app.events, event_id)][len(seqs) :]
        assert again and all(p["seq"] == max(seqs) and p["terminal"] for p in again), again

        # the operator's view: one member left, the killed one's robots listed as taken over
        status = subprocess.run(
            [sys.executable, "-m", "td2adaptor", "fleet", "status", "--bus", broker.url],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert status.returncode == 0, status.stderr
        lines_out = status.stdout.splitlines()
        assert any(line.split()[:2] == ["FLEET", "MEMBER"] for line in lines_out), status.stdout
        (member,) = [line for line in lines_out if line.startswith("share_test ")]
        assert f"{other.proc.pid}@" in member and member.split()[-2:] == ["4", "2"], member
        for robot in theirs:
            (row,) = [line for line in lines_out if line.startswith(f"{robot} ") and "takeover" in line]
            taken_by, taken_from = row.split()[1:3]
            assert taken_by.startswith(f"{other.proc.pid}@") and taken_from.startswith(f"{victim.proc.pid}@"), row

        # a process started again takes its share back by hand-over: no robot goes offline
        joined = time.monotonic()
        again_run = RunProcess(run_args("--config", str(fleet), "--share"), env=environ)
        runs.append(again_run)
        again_run.wait_ready()
        assert until(lambda: set(shares(watch).values()) == {2} and again_run.proc.pid in shares(watch), 30)
        late = [
            e["payload"]["state"]
            for (t, e), when in zip(list(watch.app.events), list(watch.came), strict=False)
            if when > joined and t.endswith("/status") and t.split("/")[1] in ROBOTS
        ]
        assert "offline" not in late, late
    finally:
        for run in runs:
            run.terminate(signal.SIGTERM)
        watch.close()
