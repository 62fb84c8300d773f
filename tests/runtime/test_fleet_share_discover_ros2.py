"""`td2adaptor run --share --discover` and admin requests in a shared fleet (issue 32, node/share.py), for real:
real `td2adaptor run` processes, the simulated RB-1s (ROS 2) in processes of their own, a real mosquitto.

Each process discovers the robots its ROS graph shows and lists them in its member record; the share gives
each robot to one of the processes that see it. Two ROS domains make "see" differ: the robots of the second
domain can only be served by the process on it. An admin request reaches the shared fleet once (one answer),
every member learns the robot, one serves it; removed, it goes offline with its TD cleared. Robots gone from
the graph are retired the same way. No process restarts meanwhile.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
import uuid
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from td2adaptor.runtime.events import now_rfc3339
from td2adaptor.runtime.node.admin import admin_topics, sign
from td2adaptor.runtime.node.graphwatch import PERIOD
from tests.ros2 import env
from tests.ros2.common import Process
from tests.runtime.broker import Mosquitto
from tests.runtime.edge import RunProcess, check_mission, stretched, until
from tests.runtime.rb1 import GOAL, terminal
from tests.runtime.test_fleet_changes_ros2 import ADMIN_KEY, Watch, goto, mission, node_env, run_args, sim_process
from tests.runtime.test_fleet_share import bridged

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

FLEET = "sdx"
FIRST = ("sd_a", "sd_b", "sd_c", "sd_d")  # on the first of the test's ROS domains: processes 1 and 3 see them
SECOND = ("sd_e", "sd_f")  # on a domain of their own: only process 2 sees them
#: issue 32: a robot is served within 2 s of its appearance in the ROS graph. Asserted from the moment a process's
#: discovery listed it (its member record) to its `online` status: the other processes' looks (at once, and
#: share.UNSEEN_AFTER later, when one lists a robot they do not: share.py `_heard`) and the start (its ROS clients,
#: its connection), with one look's period (graphwatch.PERIOD) left for the look that finds it. Not from the
#: simulation's "ready": how long ROS 2's own discovery takes to show a new process's servers to another process
#: is no edge node's doing, and on a loaded machine it took up to 2.3 s (docs/fleet.md has the figures)
SERVED_WITHIN = 2.0


def served_within() -> float:
    """`SERVED_WITHIN`, stretched on a machine busier than its cores (tests/runtime/edge.py `stretched`)."""
    return stretched(SERVED_WITHIN)


def settings(path: Path, broker: Mosquitto, tmp_path: Path, *robots: tuple[str, str]) -> None:
    lines = [f"bus: {broker.url}", "poll_period: 0.1", "property_period: 0", "call_timeout: 5"]
    lines += [f"state_dir: {tmp_path / 'state'}", f"fleet: {FLEET}"]
    if robots:
        lines += ["robots:", *(f"  - {{robot: {r}, namespace: {ns}}}" for r, ns in robots)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def owners(watch: Watch) -> dict[str, tuple[str, int | None]]:
    """Each robot's last status: (state, owner pid)."""
    out: dict[str, tuple[str, int | None]] = {}
    for t, e in list(watch.app.events):
        parts = t.split("/")
        if len(parts) == 3 and parts[2] == "status" and not parts[1].startswith("."):
            p = e["payload"]
            out[parts[1]] = (p["state"], (p.get("owner") or {}).get("pid"))
    return out


def members(watch: Watch) -> dict[str, dict[str, Any]]:
    """Each live member's last record (node -> record)."""
    out: dict[str, dict[str, Any]] = {}
    prefix = f"td2adaptor/.fleet/{FLEET}/members/"
    for t, e in list(watch.app.events):
        if t.startswith(prefix) and t.count("/") == 4:
            node = t[len(prefix) :]
            if e.get("raw") == "":
                out.pop(node, None)
            else:
                out[node] = e
    return out


def listed_at(watch: Watch, robot: str) -> float | None:
    """When a member record first listed `robot` (one of the processes saw it in its ROS graph)."""
    prefix = f"td2adaptor/.fleet/{FLEET}/members/"
    for (t, e), when in zip(list(watch.app.events), list(watch.came), strict=False):
        if t.startswith(prefix) and robot in (e.get("can") or ()):
            return when
    return None


def one_owner_each(watch: Watch, robots: set[str], pids: set[int]) -> bool:
    """Every robot of `robots` online with a process of `pids`, and the member records agree: each robot in the
    `robots` of exactly one member, that process."""
    now = owners(watch)
    if not all(now.get(r, ("", None))[0] == "online" and now[r][1] in pids for r in robots):
        return False
    served: dict[str, list[int]] = {}
    for record in members(watch).values():
        for robot in record.get("robots", []):
            served.setdefault(robot, []).append(record["owner"]["pid"])
    return all(served.get(r) == [now[r][1]] for r in robots)


def retained_td_cleared(broker: Mosquitto, robot: str) -> bool:
    """No retained TD for `robot` on the broker (a fresh subscriber gets none)."""
    from tests.runtime.client import AppClient

    reader = AppClient(broker.url, [f"td2adaptor/{robot}/td"])
    try:
        time.sleep(0.3)  # the retained message comes right after the SUBACK, which the client waited for
        return not [e for t, e in reader.events if e != {"raw": ""}]
    finally:
        reader.close()


class Admin:
    """Signed admin requests of the fleet, and every answer each one got."""

    def __init__(self, watch: Watch) -> None:
        self.watch = watch
        self.request, self.answer = admin_topics("td2adaptor", FLEET)

    def answers(self, rid: str) -> list[dict[str, Any]]:
        return [e for t, e in list(self.watch.app.events) if t == self.answer and e.get("correlation") == rid]

    def ask(self, body: dict[str, Any], key: str | None = ADMIN_KEY) -> dict[str, Any]:
        """Send a request; its one answer (a second one, from another process, would be seen in the extra second)."""
        body = {"id": f"adm-{time.monotonic_ns()}", "time": now_rfc3339(), **body}
        self.send(sign(body, key) if key else body)
        return self.one(body["id"])

    def send(self, body: dict[str, Any]) -> None:
        self.watch.app.send(self.request, body)

    def one(self, rid: str) -> dict[str, Any]:
        assert until(lambda: bool(self.answers(rid)), 30), rid
        time.sleep(1.0)  # every process read the request at once: another answer would have come by now
        got = self.answers(rid)
        assert len(got) == 1, got
        return got[0]["payload"]  # type: ignore[no-any-return]


def wait(predicate: Callable[[], bool], timeout: float, watch: Watch, *more: Callable[[], Any]) -> None:
    """`predicate` within `timeout`; else fail saying, as they are then, each robot's state and owner, what each
    member says it serves and lists, and `more`."""
    if until(predicate, timeout, 0.05):
        return
    records = {m["owner"]["pid"]: {k: m.get(k) for k in ("robots", "can", "admin")} for m in members(watch).values()}
    said = [owners(watch), records, *(c() for c in more)]
    raise AssertionError("\n".join(json.dumps(c, sort_keys=True, default=str) for c in said))


def test_shared_processes_discover_robots_each_served_by_one_that_sees_it_and_admin_requests_reach_the_fleet(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, broker: Mosquitto, tmp_path: Path
) -> None:
    # two domains of this test's own: the worker's holds other modules' simulated robots, which discovery
    # would serve too
    first_domain, other_domain = env.private_domain_id(), env.private_domain_id()
    defaults = tmp_path / "defaults.yaml"
    settings(defaults, broker, tmp_path)
    watch = Watch(broker, "share-discover-app")
    admin = Admin(watch)
    args = run_args("--config", str(defaults), "--share", "--discover", "--discover-grace", "1")
    domains = [first_domain, other_domain, first_domain]
    runs = [
        RunProcess(args, env=node_env(rb1_prefix, adaptor_build, TD2ADAPTOR_FLEET_ADMIN_KEY=ADMIN_KEY, **extra))
        for extra in [{"ROS_DOMAIN_ID": str(d)} for d in domains]
    ]
    sims: list[Process] = []
    try:
        for run in runs:
            run.wait_ready()
            assert "serving its share of fleet sdx (now 0 robots)" in run.output(), run.output()
        ready = time.monotonic()
        first, second, third = (r.proc.pid for r in runs)
        pids = {first, second, third}
        # the second domain's robots first; then, the processes' first plans made (each gives out at once what is
        # listed then), the first domain's: both of its processes list them, the other one says it does not see them
        sims.append(sim_process(rb1_prefix, SECOND, domain=other_domain))
        wait(lambda: one_owner_each(watch, set(SECOND), pids), 30, watch)
        assert until(lambda: time.monotonic() - ready > 1.5, 2)  # the first plans: 1 s after each process joined
        launched = time.monotonic()
        sims.insert(0, sim_process(rb1_prefix, FIRST, domain=first_domain))
        appeared = time.monotonic()  # when the test read that its simulation is ready
        everyone = {*FIRST, *SECOND}
        wait(lambda: one_owner_each(watch, everyone, pids), 30, watch)
        # online since the launch: on a loaded machine a process can serve a robot before the test has read the
        # simulation's `ready` (its nodes are in the graph before it prints it; seen in a loaded full run)
        online = {r: watch.status_at(r, "online", launched) or 1e9 for r in FIRST}
        listed = {r: listed_at(watch, r) or 1e9 for r in FIRST}
        took = max(online[r] - listed[r] for r in FIRST)
        print(f"appeared -> online with one of the processes that see it: max {max(online.values()) - appeared:.2f} s")
        print(
            f"  of which the ROS graph (appeared -> a process listed it): max {max(listed.values()) - appeared:.2f} s"
        )
        print(f"  and the share (listed -> online): max {took:.2f} s; load average {os.getloadavg()[0]:.1f}")
        assert took + PERIOD <= served_within(), (took, os.getloadavg())
        # both see them: a share each (one whose graph showed them later than the other's is handed its share)
        wait(lambda: {owners(watch)[r][1] for r in FIRST} == {first, third}, 10, watch)
        wait(lambda: one_owner_each(watch, everyone, pids), 10, watch)
        now = owners(watch)
        assert {now[r][1] for r in SECOND} == {second}, now  # only it sees them
        records = {m["owner"]["pid"]: m for m in members(watch).values()}
        assert set(records[second]["can"]) == set(SECOND) and set(records[first]["can"]) == set(FIRST), records
        for robot in ("sd_a", "sd_e"):
            mission(watch, robot, f"{robot}-m1")
        for robot in ("sd_a", "sd_e"):
            watch.app.wait(terminal("feedback", f"{robot}-m1"), timeout=30)
            check_mission(watch.app.events, f"{robot}-m1", ["queued", "running", "finished"])

        # an admin request reaches the shared fleet: one answer, every member lists the robot, one serves it
        sent = time.monotonic()
        body = sign(
            {"id": "adm-add", "time": now_rfc3339(), "op": "add", "robot": "adm_1", "namespace": "sd_z"}, ADMIN_KEY
        )
        admin.send(body)
        added = admin.one("adm-add")
        assert (added["code"], added["robot"]) == ("added", "adm_1"), added
        owner = owners(watch)["adm_1"]
        assert owner[0] == "online" and owner[1] in pids, owner
        assert f"served by process {owner[1]} on " in added["message"], added
        print(f"admin add -> online: {(watch.status_at('adm_1', 'online', sent) or 1e9) - sent:.2f} s")
        wait(lambda: all("adm_1" in m.get("admin", []) for m in members(watch).values()), 10, watch)
        wait(lambda: one_owner_each(watch, everyone | {"adm_1"}, pids), 10, watch)
        admin.send(body)  # the same request again: refused once
        wait(lambda: len(admin.answers("adm-add")) == 2, 30, watch, lambda: admin.answers("adm-add"))
        time.sleep(1.0)  # another answer would have come by now
        assert [a["payload"]["code"] for a in admin.answers("adm-add")] == ["added", "replayed"]
        assert admin.ask({"op": "add", "robot": "sd_b", "namespace": "sd_b"})["code"] == "served-already"
        assert admin.ask({"op": "remove", "robot": "adm_1"}, key=None)["code"] == "unauthorised"
        refused = admin.ask({"op": "remove", "robot": "sd_a"})
        assert refused["code"] == "invalid" and "fleet file, or the ROS graph" in refused["message"], refused
        assert owners(watch)["sd_a"][0] == "online"

        removed = admin.ask({"op": "remove", "robot": "adm_1"})
        assert removed["code"] == "removed", removed
        assert owners(watch)["adm_1"][0] == "offline", (watch.statuses("adm_1"), [r.output()[-4000:] for r in runs])
        assert retained_td_cleared(broker, "adm_1")
        wait(lambda: not any("adm_1" in m.get("admin", []) for m in members(watch).values()), 10, watch)
        assert admin.ask({"op": "remove", "robot": "adm_1"})["code"] == "not-served"

        # robots gone from the ROS graph are retired: offline, TD cleared; the others untouched
        gone = time.monotonic()
        sims.pop().stop()
        wait(lambda: all(owners(watch)[r][0] == "offline" for r in SECOND), 30, watch)
        print(f"gone -> offline: {max((watch.status_at(r, 'offline', gone) or 1e9) - gone for r in SECOND):.2f} s")
        for robot in SECOND:
            assert retained_td_cleared(broker, robot), robot
        wait(lambda: one_owner_each(watch, set(FIRST), pids), 10, watch)
        assert [r.proc.poll() for r in runs] == [None, None, None]  # no process restarted
        for run in runs:
            assert "Traceback" not in run.output(), run.output()
            assert ADMIN_KEY not in run.output()
    finally:
        for sim in sims:
            sim.stop()
        codes = [run.terminate(signal.SIGTERM) for run in runs]
        watch.close()
    assert codes == [0, 0, 0], [run.output()[-3000:] for run in runs]


class Missions:
    """One mission after the other on each robot of `robots`, each with its own id and time; one whose terminal
    event does not come within 20 s is sent again under its id (a known gap, docs/fleet.md: a command acknowledged
    by a process whose engine had stopped taking events at a hand-over; the replay guard runs it once)."""

    def __init__(self, watch: Watch, robots: tuple[str, ...]) -> None:
        self.watch = watch
        self.sent: dict[str, list[str]] = {r: [] for r in robots}
        self.resent = 0
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=self._run, args=(r,), daemon=True) for r in robots]

    def start(self) -> None:
        for thread in self._threads:
            thread.start()

    def _run(self, robot: str) -> None:
        while not self._stop.is_set():
            event_id = uuid.uuid4().hex
            self.sent[robot].append(event_id)
            invoke = {"id": event_id, "time": now_rfc3339(), "correlation": event_id, "payload": GOAL}
            for _ in range(3):
                self.watch.app.send(goto(robot), invoke)
                try:
                    self.watch.app.wait(terminal("feedback", event_id), timeout=20)
                    break
                except (AssertionError, TimeoutError):
                    self.resent += 1

    def stop(self) -> None:
        self._stop.set()
        for thread in self._threads:
            if thread.is_alive():  # never started when the test failed before: nothing to join
                thread.join(90)


def test_three_shared_processes_discover_reload_under_load_over_bridged_brokers_and_every_robot_has_one_owner(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, tmp_path: Path
) -> None:
    """Issue 32's scenario in one run: 3 `run --share --discover` processes on a site mosquitto bridged to a central
    one (the application there), a fleet file of 2 robots, 5 robots discovered at the start, 3 more appearing
    later and then gone, and a SIGHUP to every process that replaces a file robot, all while missions run on 4
    robots. 10 robots at the most, not issue 32's 30: each robot is an rclpy node's clients in one of the
    processes plus its simulated twin, and with 3 edge processes, 2 simulations, 2 brokers and the missions on a
    2-core CI machine shared with another test worker, more would make it slow (over a minute) rather than show
    more. Asserted: every robot served by exactly one process (its status and the member records agree), every
    mission answered exactly once and started once on its robot, the removed robots `offline` with their TD
    cleared, no process restarted."""
    site, central = bridged(tmp_path)
    fleet = tmp_path / "fleet.yaml"
    settings(fleet, site, tmp_path, ("cf_1", "cx_f1"), ("cf_2", "cx_f2"))
    watch = Watch(central, "combined-app")
    found = ("cx_1", "cx_2", "cx_3", "cx_4", "cx_5")
    later = ("cx_6", "cx_7", "cx_8")
    domain = env.private_domain_id()  # the worker's holds other modules' simulated robots: discovery would serve them
    sims = [sim_process(rb1_prefix, ("cx_f1", "cx_f2", *found), domain=domain)]
    # a grace of 3 s: on a loaded machine a robot's services may be missing from one look at the graph
    args = run_args("--config", str(fleet), "--share", "--discover", "--discover-grace", "3")
    runs = [RunProcess(args, env=node_env(rb1_prefix, adaptor_build, ROS_DOMAIN_ID=str(domain))) for _ in range(3)]
    busy = ("cf_1", "cx_1", "cx_2", "cx_3")
    missions = Missions(watch, busy)
    began = time.monotonic()
    try:
        for run in runs:
            run.wait_ready()
        pids = {r.proc.pid for r in runs}
        first = {"cf_1", "cf_2", *found}
        # a process that took its share before the others joined hands robots over until the shares are fair
        fair = lambda: set(Counter(owners(watch)[r][1] for r in first).values()) <= {2, 3}  # noqa: E731
        wait(lambda: one_owner_each(watch, first, pids) and fair(), 40, watch)
        missions.start()
        assert until(lambda: all(len(v) >= 2 for v in missions.sent.values()), 30)

        launched = time.monotonic()
        sims.append(sim_process(rb1_prefix, later, domain=domain))  # robots appear
        appeared = time.monotonic()
        simulations = lambda: [(sim.proc.poll(), sim.stderr_tail(500)) for sim in sims]  # noqa: E731
        wait(lambda: one_owner_each(watch, first | set(later), pids), 30, watch, simulations)
        # from the test's reading of `ready`; online before it (a loaded machine) counts as at once
        took = max((watch.status_at(r, "online", launched) or 1e9) - appeared for r in later)
        print(f"appeared -> online: max {took:.2f} s")

        settings(fleet, site, tmp_path, ("cf_1", "cx_f1"), ("cf_3", "cx_f2"))  # cf_2 leaves, cf_3 joins
        for run in runs:
            run.proc.send_signal(signal.SIGHUP)
        now = first - {"cf_2"} | {"cf_3"} | set(later)
        wait(lambda: one_owner_each(watch, now, pids) and owners(watch)["cf_2"][0] == "offline", 30, watch, simulations)

        gone = time.monotonic()
        sims.pop().stop()  # robots leave the ROS graph
        wait(lambda: all(owners(watch)[r][0] == "offline" for r in later), 30, watch)
        print(f"gone -> offline: max {max((watch.status_at(r, 'offline', gone) or 1e9) - gone for r in later):.2f} s")
        assert until(lambda: all(len(v) >= 6 for v in missions.sent.values()), 40), missions.sent
        missions.stop()

        final = first - {"cf_2"} | {"cf_3"}
        wait(lambda: one_owner_each(watch, final, pids), 10, watch)
        for robot in ("cf_2", *later):
            assert owners(watch)[robot][0] == "offline", robot
            assert retained_td_cleared(central, robot), robot
        for ids in missions.sent.values():  # each answered once, with one end
            for event_id in ids:
                check_mission(watch.app.events, event_id, ["queued", "running", "finished"])
        starts = Counter(e["robot"] for e in sims[0].drain() if e.get("event") == "call" and e.get("op") == "add")
        namespace = {"cf_1": "cx_f1"}
        assert {r: starts[namespace.get(r, r)] for r in busy} == {r: len(v) for r, v in missions.sent.items()}
        assert [r.proc.poll() for r in runs] == [None, None, None]  # no process restarted
        assert {p for _s, p in owners(watch).values()} <= pids
        for run in runs:
            assert "Traceback" not in run.output(), run.output()
        print(
            f"{sum(len(v) for v in missions.sent.values())} missions, {missions.resent} sent again; "
            f"{time.monotonic() - began:.0f} s"
        )
    finally:
        missions.stop()
        for sim in sims:
            sim.stop()
        codes = [run.terminate(signal.SIGTERM) for run in runs]
        watch.close()
        site.stop()
        central.stop()
    assert codes == [0, 0, 0], [run.output()[-3000:] for run in runs]


#: issue 32's scenario at its scale (`bench/fleet_takeover.py --scenario 30` sets it): too heavy for the suite on
#: a 2-core machine (3 edge processes, 3 simulations of 20 + 5 + 5 robots, the missions, two brokers)
SCENARIO = int(os.environ.get("TD2ADAPTOR_SHARE_SCENARIO_ROBOTS", "0"))


def _quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def scenario_at_scale(adaptor_build: tuple[Path, Path], rb1_prefix: Path, tmp_path: Path) -> None:
    """Three `run --share --discover` processes on a site mosquitto bridged to a central one (the application
    there), SCENARIO robots at the peak: 2 in the fleet file, SCENARIO - 12 discovered at the start, 10 added
    (two simulations of 5), 5 removed (one of them stopped), a SIGHUP that replaces a file robot, and a kill -9
    of one process, all under missions sent one after the other on every robot served from the start but the one
    the SIGHUP removes (each mission 2 s on the simulated robot). Printed: the figures (one JSON line,
    `SCENARIO`). Asserted: no command ran twice, none lost, every robot one owner, the removed ones `offline` with
    no TD."""
    n = SCENARIO
    site, central = bridged(tmp_path)
    fleet = tmp_path / "fleet.yaml"
    settings(fleet, site, tmp_path, ("cf_1", "cx_f1"), ("cf_2", "cx_f2"))
    watch = Watch(central, "scenario-app")
    found = tuple(f"cx_{i:02d}" for i in range(n - 12))
    added, removed = tuple(f"ca_{i}" for i in range(5)), tuple(f"cr_{i}" for i in range(5))
    domain = env.private_domain_id()
    sims = [sim_process(rb1_prefix, ("cx_f1", "cx_f2", *found), domain=domain)]
    args = run_args("--config", str(fleet), "--share", "--discover", "--discover-grace", "3")
    runs = [RunProcess(args, env=node_env(rb1_prefix, adaptor_build, ROS_DOMAIN_ID=str(domain))) for _ in range(3)]
    first = {"cf_1", "cf_2", *found}
    missions = Missions(watch, tuple(sorted(first - {"cf_2"})))  # cf_2 leaves the fleet file on the way
    figures: dict[str, Any] = {"robots": n, "load_before": os.getloadavg()[0]}
    began = time.monotonic()
    try:
        for run in runs:
            run.wait_ready()
        pids = {r.proc.pid for r in runs}
        even = {len(first) // 3, -(-len(first) // 3)}
        fair = lambda: set(Counter(owners(watch)[r][1] for r in first).values()) <= even  # noqa: E731
        wait(lambda: one_owner_each(watch, first, pids) and fair(), 120, watch)
        figures["start_s"] = round(time.monotonic() - began, 2)
        missions.start()
        assert until(lambda: all(len(v) >= 2 for v in missions.sent.values()), 60)

        # add 10: two simulations of 5
        appeared = time.monotonic()
        sims += [sim_process(rb1_prefix, added, domain=domain), sim_process(rb1_prefix, removed, domain=domain)]
        ready = time.monotonic()
        wait(lambda: one_owner_each(watch, first | set(added) | set(removed), pids), 60, watch)
        new = (*added, *removed)
        online = {r: watch.status_at(r, "online", appeared) or 1e9 for r in new}
        listed = {r: listed_at(watch, r) or 1e9 for r in new}
        figures["added_ready_to_online_max_s"] = round(max(online.values()) - ready, 2)
        figures["added_listed_to_online_max_s"] = round(max(online[r] - listed[r] for r in new), 2)
        figures["load_at_add"] = os.getloadavg()[0]

        # remove 5: their simulation stops
        gone = time.monotonic()
        sims.pop().stop()
        wait(lambda: all(owners(watch)[r][0] == "offline" for r in removed), 60, watch)
        figures["removed_to_offline_max_s"] = round(
            max((watch.status_at(r, "offline", gone) or 1e9) - gone for r in removed), 2
        )

        # SIGHUP under load: cf_2 leaves, cf_3 joins
        settings(fleet, site, tmp_path, ("cf_1", "cx_f1"), ("cf_3", "cx_f2"))
        for run in runs:
            run.proc.send_signal(signal.SIGHUP)
        now = first - {"cf_2"} | {"cf_3"} | set(added)
        wait(lambda: one_owner_each(watch, now, pids) and owners(watch)["cf_2"][0] == "offline", 60, watch)

        # kill -9 one process under load
        victim = runs[0]
        theirs = {r for r, (state, pid) in owners(watch).items() if pid == victim.proc.pid and state == "online"}
        killed = time.monotonic()
        victim.proc.kill()
        victim.proc.wait(10)
        survivors = pids - {victim.proc.pid}
        wait(lambda: one_owner_each(watch, now, survivors), 60, watch)
        back = []
        for robot in theirs:
            when = next(
                (
                    t
                    for (topic, e), t in zip(list(watch.app.events), list(watch.came), strict=False)
                    if topic == f"td2adaptor/{robot}/status"
                    and t >= killed
                    and e["payload"]["state"] == "online"
                    and (e["payload"].get("owner") or {}).get("pid") in survivors
                ),
                None,
            )
            back.append((when or 1e9) - killed)
        figures["killed_robots"] = len(theirs)
        figures["takeover_p50_s"] = round(_quantile(back, 0.5), 2)
        figures["takeover_p99_s"] = round(_quantile(back, 0.99), 2)
        figures["takeover_max_s"] = round(max(back), 2)
        figures["load_at_kill"] = os.getloadavg()[0]
        sent_before = {r: len(v) for r, v in missions.sent.items()}
        assert until(lambda: all(len(v) >= sent_before[r] + 2 for r, v in missions.sent.items() if r in now), 90)
        missions.stop()

        ends: dict[str, list[str]] = {}
        why: Counter[str] = Counter()  # the words of the ends that are not `finished` (their first 60 characters)
        for _topic, e in list(watch.app.events):
            if e.get("type") == "feedback" and (e.get("payload") or {}).get("terminal"):
                ends.setdefault(str(e.get("correlation")), []).append(e["payload"].get("state", ""))
                if e["payload"].get("state") != "finished":
                    why[str(e["payload"].get("message", ""))[:60]] += 1
        sent = [i for v in missions.sent.values() for i in v]
        lost = [i for i in sent if i not in ends]
        twice = [i for i in sent if len(ends.get(i, [])) > 1]
        states = Counter(ends[i][0] for i in sent if i in ends)
        starts = Counter(e["robot"] for e in sims[0].drain() if e.get("event") == "call" and e.get("op") == "add")
        namespace = {"cf_1": "cx_f1", "cf_2": "cx_f2", "cf_3": "cx_f2"}
        ran: Counter[str] = Counter()
        for robot, ids in missions.sent.items():
            ran[namespace.get(robot, robot)] += len(ids)
        duplicated = {ns: starts[ns] - count for ns, count in ran.items() if starts[ns] > count}
        figures |= {
            "missions": len(sent),
            "sent_again": missions.resent,
            "ends": dict(states),
            "not_finished_why": dict(why),
            "lost": len(lost),
            "answered_twice": len(twice),
            "commands_run_twice": sum(duplicated.values()),
            "wall_s": round(time.monotonic() - began, 1),
        }
        print("SCENARIO " + json.dumps(figures, sort_keys=True))
        assert not duplicated, duplicated
        assert not lost and not twice, (lost[:5], twice[:5])
        for robot in ("cf_2", *removed):
            assert owners(watch)[robot][0] == "offline", robot
            assert retained_td_cleared(central, robot), robot
        assert [r.proc.poll() for r in runs[1:]] == [None, None]  # the survivors did not restart
        for run in runs[1:]:
            assert "Traceback" not in run.output(), run.output()[-3000:]
    finally:
        missions.stop()
        for sim in sims:
            sim.stop()
        codes = [run.terminate(signal.SIGTERM) for run in runs[1:]]
        runs[0].terminate(signal.SIGKILL)
        watch.close()
        site.stop()
        central.stop()
    assert codes == [0, 0], [run.output()[-3000:] for run in runs[1:]]


if SCENARIO >= 12:  # asked for by bench/fleet_takeover.py --scenario N only: too heavy for the suite's 2 cores
    test_issue_32_scenario_at_scale = scenario_at_scale
