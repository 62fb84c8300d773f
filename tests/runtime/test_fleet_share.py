"""Several edge-node processes share one fleet through the broker (issue 32, node/share.py): real mosquitto, real
processes (tests/runtime/share_proc.py, their robots simulated), a real kill -9.

* three processes share 30 robots: each robot served by exactly one, 10 each;
* one is killed (SIGKILL) under 1 mission per second per robot: its robots are served again within 5 s, no
  mission runs twice (every process writes each mission it starts to one file), an invoke sent again under its
  id after the takeover is answered, not run, and the statuses, TDs and member records agree afterwards;
* a process that joins later takes its share, handed over without any robot going `offline`, and hands it back
  when it stops;
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt

from td2adaptor.runtime.events import now_rfc3339
from td2adaptor.runtime.node.shareplan import assign
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until

ROBOTS = 30
INVOKE = "td2adaptor/{robot}/GoToComponent/gotoRun"


class Watcher(AppClient):
    """Records every event with the time it arrived."""

    def __init__(self, broker: Mosquitto) -> None:
        self.times: list[float] = []
        super().__init__(broker, ["td2adaptor/#"])

    def _on_message(self, c: mqtt.Client, u: Any, msg: mqtt.MQTTMessage) -> None:
        with self.cond:
            self.times.append(time.monotonic())
        super()._on_message(c, u, msg)

    def timed(self) -> list[tuple[float, str, dict[str, Any]]]:
        with self.cond:
            return [
                (t, topic, e) for t, (topic, e) in zip(self.times, self.events, strict=False) if isinstance(e, dict)
            ]

    def statuses(self) -> Iterator[tuple[float, str, dict[str, Any]]]:
        for t, topic, e in self.timed():
            parts = topic.split("/")
            if len(parts) == 3 and parts[2] == "status" and not parts[1].startswith("."):
                yield t, parts[1], e.get("payload", {})

    def owners(self) -> dict[str, tuple[str, int | None]]:
        """Each robot's last status: (state, owner pid)."""
        out: dict[str, tuple[str, int | None]] = {}
        for _t, robot, p in self.statuses():
            out[robot] = (p.get("state", ""), (p.get("owner") or {}).get("pid"))
        return out

    def terminals(self) -> dict[str, list[dict[str, Any]]]:
        out: dict[str, list[dict[str, Any]]] = {}
        for _t, _topic, e in self.timed():
            if e.get("type") == "feedback" and e.get("payload", {}).get("terminal"):
                out.setdefault(str(e.get("correlation")), []).append(e["payload"])
        return out


class Load:
    """One invoke per robot per second, each with its own id and a goal x no other invoke has."""

    def __init__(self, broker: Mosquitto, robots: list[str]) -> None:
        self.client = AppClient(broker, ["test/nothing"])
        self.robots = robots
        self.sent: dict[str, tuple[str, str, dict[str, Any]]] = {}  # id -> (robot, topic, event)
        self.sent_at: dict[str, float] = {}  # id -> when it was sent (time.monotonic())
        self._stop = threading.Event()
        self._n = 0
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            began = time.monotonic()
            for robot in self.robots:
                self._n += 1
                event_id = uuid.uuid4().hex
                event = {
                    "id": event_id,
                    "time": now_rfc3339(),
                    "correlation": event_id,
                    "payload": {"procedure": {"goals": [{"pose": {"x": 1.0 + self._n / 10000, "y": 3.0}}]}},
                }
                topic = INVOKE.format(robot=robot)
                self.sent[event_id] = (robot, topic, event)
                self.sent_at[event_id] = time.monotonic()
                self.client.send(topic, event)
            self._stop.wait(max(0.0, 1.0 - (time.monotonic() - began)))

    def stop(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(10)
        self.client.close()


class Procs:
    """The processes of one shared fleet of `robots` simulated robots (tests/runtime/share_proc.py)."""

    def __init__(self, broker: Mosquitto, tmp: Path, robots: int = ROBOTS, *, hosts: bool = False) -> None:
        self.broker = broker
        self.tmp = tmp
        self.robots = robots
        self.hosts = hosts  # each process a state directory of its own, as on several hosts
        self.runs = tmp / "runs.txt"
        self.procs: list[subprocess.Popen[str]] = []
        self.files: list[Any] = []

    def start(self) -> subprocess.Popen[str]:
        return self.start_many(1)[0]

    def start_many(self, count: int) -> list[subprocess.Popen[str]]:
        """`count` processes started together (each waits a moment for the others before it takes its share)."""
        started = []
        for _ in range(count):
            log = open(self.tmp / f"proc{len(self.procs)}.log", "w")  # noqa: SIM115 - the child's, closed in close()
            self.files.append(log)
            proc = subprocess.Popen(
                [sys.executable, "-m", "tests.runtime.share_proc", self.broker.url, str(self.tmp / "state")]
                + [str(self.robots), str(self.runs), *(["own"] if self.hosts else [])],
                stdout=subprocess.PIPE,
                stderr=log,
                text=True,
            )
            self.procs.append(proc)
            started.append(proc)
        for proc in started:
            assert proc.stdout is not None
            assert proc.stdout.readline().startswith("ready"), self.logs()
        return started

    def logs(self, *, whole: bool = False) -> str:
        texts = [(self.tmp / f"proc{i}.log").read_text() for i in range(len(self.procs))]
        return "\n".join(f"--- proc{i}\n{t if whole else t[-3000:]}" for i, t in enumerate(texts))

    def runs_of(self) -> Counter[str]:
        """How often each goal x was started, over every process."""
        lines = self.runs.read_text().splitlines() if self.runs.exists() else []
        return Counter(" ".join(line.split()[:2]) for line in lines)

    def close(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        for proc in self.procs:
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            if proc.stdout is not None:
                proc.stdout.close()
        for f in self.files:
            f.close()


def shares(watcher: Watcher, pids: set[int]) -> Counter[int | None]:
    owners = watcher.owners()
    return Counter(pid for state, pid in owners.values() if state == "online" and pid in pids)


def shares_pid(watcher: Watcher, robot: str) -> int | None:
    return watcher.owners()[robot][1]


def served_by(watcher: Watcher, pids: set[int], robots: int = ROBOTS) -> bool:
    owners = watcher.owners()
    return len(owners) == robots and all(s == "online" and p in pids for s, p in owners.values())


def every_invoke_answered(load: Load, watcher: Watcher, procs: Procs | None = None) -> None:
    """Every invoke gets its terminal event, also one the killed process had read in its last moment (it did not
    acknowledge it before admitting it: the broker gave it to the next owner) or one that reached the old owner
    of a robot handed over after its engine stopped (not acknowledged either). Nothing is sent again."""

    def unanswered() -> set[str]:
        return set(load.sent) - set(watcher.terminals())

    if until(lambda: not unanswered(), 30):
        return
    missing = sorted(unanswered(), key=lambda i: load.sent_at[i])
    robots = {load.sent[i][0] for i in missing}
    # what a failure needs to be understood (a whole run at load 28 once left two robots' invokes unanswered)
    timeline = [(round(t, 2), r, p.get("state"), (p.get("owner") or {}).get("pid")) for t, r, p in watcher.statuses()]
    lines = [f"unanswered: {[(load.sent[i][0], round(load.sent_at[i], 2), i[:8]) for i in missing]}"]
    lines.append(f"statuses of {sorted(robots)}: {[s for s in timeline if s[1] in robots]}")
    if procs is not None:
        lines.append(procs.logs(whole=True))
    raise AssertionError("\n".join(lines))


def retained(broker: Mosquitto, pattern: str) -> dict[str, dict[str, Any]]:
    """The retained messages under `pattern`, read by a fresh client: all of them, however loaded the machine
    (30 TDs took longer than a fixed half second once). A message the client publishes to itself after its
    SUBACK comes after every retained one: the broker queues them in order on the one connection."""
    marker = f"td2adaptor-tests/retained/{uuid.uuid4().hex}"
    reader = AppClient(broker, [pattern, marker])
    try:
        reader.send(marker, {"marker": True})
        reader.wait(lambda events: any(t == marker for t, _ in events), 30)
        return {t: e for t, e in list(reader.events) if t != marker}
    finally:
        reader.close()


def test_the_assignment_is_the_same_everywhere_fair_and_moves_little() -> None:
    robots = [f"rb_{i:02d}" for i in range(ROBOTS)]
    for seed in range(20):
        members = [f"{seed:02d}{m}" * 4 for m in "abc"]
        plan = assign(robots, members)
        assert plan == assign(list(reversed(robots)), list(reversed(members)))  # order does not matter
        assert sorted(Counter(plan.values()).values()) == [10, 10, 10]
        after = assign(robots, members[1:])  # the first one died
        assert sorted(Counter(after.values()).values()) == [15, 15]
        others_moved = [r for r in robots if plan[r] != members[0] and after[r] != plan[r]]
        assert len(others_moved) <= 4, others_moved
        assert sorted(Counter(assign(robots[:31], [*members, "late"]).values()).values()) == [7, 7, 8, 8]


def test_the_assignment_gives_each_robot_to_a_member_that_can_serve_it() -> None:
    """`can`: what each member lists (its file, what its discovery sees, the admin's). A robot only some members
    see goes to one of them, whatever the bound says (the bound still keeps a member from taking them all); the
    plan is the same everywhere, and with every member able to serve every robot it is the plan without `can`."""
    robots = [f"rb_{i:02d}" for i in range(ROBOTS)]
    for seed in range(20):
        members = [f"{seed:02d}{m}" * 4 for m in "abc"]
        a, b, c = members
        everyone = dict.fromkeys(members, set(robots))
        assert assign(robots, members, everyone) == assign(robots, members)
        can = {a: set(robots[:20]), b: set(robots[10:]), c: set(robots[:5]) | {"rb_29"}}  # nobody sees rb_99
        plan = assign([*robots, "rb_99"], members, can)
        reversed_can = {m: set(reversed(sorted(v))) for m, v in reversed(can.items())}
        assert plan == assign(list(reversed([*robots, "rb_99"])), list(reversed(members)), reversed_can)
        assert set(plan) == set(robots) and all(robot in can[member] for robot, member in plan.items())
        assert [plan[r] for r in robots[20:29]] == [b] * 9  # only b sees them
        assert max(Counter(plan.values()).values()) <= 15 and len(set(plan.values())) == 3


def test_three_processes_share_30_robots_and_a_killed_ones_robots_are_taken_over_in_5_s(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    procs = Procs(broker, tmp_path)
    watcher = Watcher(broker)
    robots = [f"rb_{i:02d}" for i in range(ROBOTS)]
    load = Load(broker, robots)
    try:
        started = procs.start_many(3)
        pids = {p.pid for p in started}
        assert until(lambda: served_by(watcher, pids) and set(shares(watcher, pids).values()) == {10}, 60), (
            watcher.owners(),
            procs.logs(),
        )
        load.start()
        time.sleep(3)
        victim = started[0]
        owned_before = {r: pid for r, (_s, pid) in watcher.owners().items()}
        theirs = [r for r, pid in owned_before.items() if pid == victim.pid]
        assert len(theirs) == 10
        killed = time.monotonic()
        victim.kill()
        victim.wait()
        survivors = pids - {victim.pid}
        assert until(lambda: served_by(watcher, survivors), 20), (watcher.owners(), procs.logs())
        back: dict[str, float] = {}
        for t, robot, p in watcher.statuses():
            if robot in theirs and t > killed and p.get("state") == "online" and p["owner"]["pid"] in survivors:
                back.setdefault(robot, t - killed)
        takeover = sorted(back.values())
        print(f"takeover after kill -9: max {takeover[-1]:.2f} s, median {takeover[len(takeover) // 2]:.2f} s")
        assert len(takeover) == 10 and takeover[-1] <= 5.0, takeover
        time.sleep(3)  # missions go on, now on the survivors
        load.stop()
        # invokes the dead process had taken, sent again under their ids: answered from the ledger, never run
        before_kill = [i for i, (robot, _t, e) in load.sent.items() if robot in theirs][:20]
        terminals_before = {i: len(watcher.terminals().get(i, [])) for i in before_kill}
        resender = AppClient(broker, ["test/nothing"])
        for event_id in before_kill:
            _robot, topic, event = load.sent[event_id]
            resender.send(topic, event)
        resender.close()
        assert until(lambda: all(len(watcher.terminals().get(i, [])) > terminals_before[i] for i in before_kill), 15)
        # every invoke ends, once, and no mission ran twice
        every_invoke_answered(load, watcher, procs)
        ends = watcher.terminals()
        outcomes = {i: {(p["state"], p.get("seq")) for p in ends[i]} for i in load.sent}
        assert all(len(o) == 1 for o in outcomes.values()), [o for o in outcomes.values() if len(o) > 1][:5]
        runs = procs.runs_of()
        assert runs and max(runs.values()) == 1, [k for k, n in runs.items() if n > 1]
        states = Counter(next(iter(o))[0] for o in outcomes.values())
        print(f"{len(load.sent)} invokes: {dict(states)}; {sum(runs.values())} missions run")
        print(Counter(p.get("message", "")[:90] for o in ends.values() for p in o if p["state"] != "finished"))
        # afterwards: statuses, TDs and member records agree
        assert set(shares(watcher, survivors).values()) == {15}
        tds = retained(broker, "td2adaptor/+/td")
        assert sorted(t.split("/")[1] for t, e in tds.items() if e) == robots
        members = retained(broker, "td2adaptor/.fleet/shared/members/+")
        records = [e for e in members.values() if e.get("owner")]
        assert {r["owner"]["pid"] for r in records} == survivors
        served = [r for rec in records for r in rec["robots"]]
        assert sorted(served) == robots
        took = {t["robot"] for rec in records for t in rec["takeovers"] if t["how"] == "takeover"}
        assert took == set(theirs)
        shown = subprocess.run(
            [sys.executable, "-m", "td2adaptor", "fleet", "status", "--bus", broker.url, "--json", "--members"],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert shown.returncode == 0, shown.stderr
        listed = json.loads(shown.stdout)
        assert sorted(m["owner"]["pid"] for m in listed) == sorted(survivors)
        # its robots, taken over from it (robots it handed over while the shares settled at the start are no takeover)
        taken = {t["robot"] for m in listed for t in m["takeovers"] if t["how"] == "takeover"}
        assert taken == set(theirs) and all(
            t["from"]["pid"] == victim.pid for m in listed for t in m["takeovers"] if t["how"] == "takeover"
        )
    finally:
        load.stop()
        watcher.close()
        procs.close()
        broker.stop()


def test_a_process_that_joins_later_takes_its_share_without_a_robot_going_offline(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    procs = Procs(broker, tmp_path)
    watcher = Watcher(broker)
    robots = [f"rb_{i:02d}" for i in range(ROBOTS)]
    load = Load(broker, robots)
    try:
        first = procs.start_many(2)
        pids = {p.pid for p in first}
        assert until(lambda: served_by(watcher, pids) and set(shares(watcher, pids).values()) == {15}, 60)
        load.start()
        time.sleep(2)
        joined = time.monotonic()
        late = procs.start()
        pids.add(late.pid)
        assert until(lambda: served_by(watcher, pids) and set(shares(watcher, pids).values()) == {10}, 30), (
            watcher.owners(),
            procs.logs(),
        )
        time.sleep(2)
        load.stop()
        assert until(lambda: set(load.sent) <= set(watcher.terminals()), 30)
        # never offline; each handed-over robot online again (the new owner) soon after the hand-over
        assert all(p.get("state") == "online" for _t, _r, p in watcher.statuses())
        handed: dict[str, tuple[float, str]] = {}  # robot -> (when, to which member) of its last hand-over
        dark: dict[str, float] = {}  # robot -> seconds from its hand-over to the new owner's online status
        for t, robot, p in watcher.statuses():
            if t < joined:
                continue
            if p.get("handover"):
                handed[robot] = (t, p["handover"]["node"])
                dark.pop(robot, None)
            elif robot in handed and p["owner"]["node"] == handed[robot][1]:
                dark.setdefault(robot, t - handed[robot][0])
        to_late = [r for r, (_t, _to) in handed.items() if shares_pid(watcher, r) == late.pid]
        assert len(to_late) == 10 and set(dark) == set(handed), (handed, dark)
        print(f"hand-over: the new owner online {max(dark.values()):.2f} s at most after the old one let go")
        assert max(dark.values()) < 5.0  # commands wait in the session meanwhile; the status stays online
        runs = procs.runs_of()
        assert max(runs.values()) == 1
        ends = watcher.terminals()
        assert all(len({(p["state"], p.get("seq")) for p in ends[i]}) == 1 for i in load.sent)
        # a mission in flight at its hand-over is the next owner's to follow: no terminal event says it was cut
        assert not [p for i in load.sent for p in ends[i] if "handed over" in p.get("message", "")]
        # the late process stops (SIGTERM): it hands its robots back before it leaves, again never offline
        stopped = time.monotonic()
        late.send_signal(signal.SIGTERM)
        assert late.wait(30) == 0
        pids.discard(late.pid)
        assert until(lambda: served_by(watcher, pids) and set(shares(watcher, pids).values()) == {15}, 30)
        after = [p for t, _r, p in watcher.statuses() if t > stopped]
        assert after and all(p.get("state") == "online" for p in after), [p for p in after if p["state"] != "online"]
    finally:
        load.stop()
        watcher.close()
        procs.close()
        broker.stop()


def bridged(tmp_path: Path) -> tuple[Mosquitto, Mosquitto]:
    """A site mosquitto bridged to a central one (`td2adaptor/#` both ways), both started: (site, central)."""
    central = Mosquitto(tmp_path / "central")
    central.start()
    site = Mosquitto(tmp_path / "site")
    with site.conf.open("a", encoding="utf-8") as conf:
        conf.write(
            "connection central\n"
            f"address 127.0.0.1:{central.port}\n"
            "topic td2adaptor/# both 1\n"
            "cleansession false\n"
            "restart_timeout 1\n"
        )
    try:
        site.start()
    except BaseException:
        central.stop()
        raise
    return site, central


def test_the_same_over_a_site_broker_bridged_to_a_central_one(tmp_path: Path) -> None:
    """The processes on the site's mosquitto, the application on a central one, bridged (`td2adaptor/#` both
    ways): the application at the centre sees the shares, the takeover and every mission's end."""
    site, central = bridged(tmp_path)
    robots = 10
    procs = Procs(site, tmp_path, robots)
    watcher = Watcher(central)
    load = Load(central, [f"rb_{i:02d}" for i in range(robots)])
    try:
        started = procs.start_many(2)
        pids = {p.pid for p in started}
        assert until(lambda: served_by(watcher, pids, robots) and set(shares(watcher, pids).values()) == {5}, 60), (
            watcher.owners(),
            procs.logs(),
        )
        load.start()
        time.sleep(3)
        victim = started[0]
        theirs = [r for r, (_s, pid) in watcher.owners().items() if pid == victim.pid]
        killed = time.monotonic()
        victim.kill()
        victim.wait()
        survivors = pids - {victim.pid}
        assert until(lambda: served_by(watcher, survivors, robots), 20), (watcher.owners(), procs.logs())
        back = {
            robot: t - killed
            for t, robot, p in reversed(list(watcher.statuses()))
            if robot in theirs and t > killed and p.get("state") == "online" and p["owner"]["pid"] in survivors
        }
        print(f"takeover seen at the central broker: max {max(back.values()):.2f} s")
        assert len(back) == 5 and max(back.values()) <= 5.0, back
        time.sleep(2)
        load.stop()
        every_invoke_answered(load, watcher, procs)
        ends = watcher.terminals()
        assert all(len({(p["state"], p.get("seq")) for p in ends[i]}) == 1 for i in load.sent)
        assert max(procs.runs_of().values()) == 1
        members = retained(central, "td2adaptor/.fleet/shared/members/+")  # the will's clearing crossed too
        assert {e["owner"]["pid"] for e in members.values() if e.get("owner")} == survivors, members
    finally:
        load.stop()
        watcher.close()
        procs.close()
        site.stop()
        central.stop()


def test_on_several_hosts_the_next_owner_learns_from_the_broker_what_the_dead_one_admitted(tmp_path: Path) -> None:
    """The processes keep their state directories apart, as on several hosts: what the killed one admitted
    reaches the next owner through the broker (node/admitted.py). Its invokes sent again are answered, not run;
    its missions in flight end with one terminal event each; no mission runs twice."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    robots = 10
    procs = Procs(broker, tmp_path, robots, hosts=True)
    watcher = Watcher(broker)
    load = Load(broker, [f"rb_{i:02d}" for i in range(robots)])
    try:
        started = procs.start_many(2)
        pids = {p.pid for p in started}
        assert until(lambda: served_by(watcher, pids, robots) and set(shares(watcher, pids).values()) == {5}, 60)
        load.start()
        time.sleep(3)
        victim = started[0]
        theirs = [r for r, (_s, pid) in watcher.owners().items() if pid == victim.pid]
        victim.kill()
        victim.wait()
        assert until(lambda: served_by(watcher, pids - {victim.pid}, robots), 20), procs.logs()
        before_kill = [i for i, (robot, _t, _e) in list(load.sent.items()) if robot in theirs]
        time.sleep(2)
        load.stop()
        terminals_before = {i: len(watcher.terminals().get(i, [])) for i in before_kill}
        resender = AppClient(broker, ["test/nothing"])
        for event_id in before_kill:
            _robot, topic, event = load.sent[event_id]
            resender.send(topic, event)
        resender.close()
        assert until(lambda: set(load.sent) <= set(watcher.terminals()), 30), procs.logs()
        assert until(lambda: all(len(watcher.terminals()[i]) > terminals_before[i] for i in before_kill), 15), [
            i for i in before_kill if len(watcher.terminals()[i]) <= terminals_before[i]
        ]
        runs = procs.runs_of()
        assert max(runs.values()) == 1, [k for k, n in runs.items() if n > 1]
        ends = watcher.terminals()
        assert all(len({(p["state"], p.get("seq")) for p in ends[i]}) == 1 for i in load.sent)
        admitted = retained(broker, "td2adaptor/.fleet/shared/admitted/+/+")
        assert {e["id"] for e in admitted.values() if e} >= set(load.sent)  # what a third owner would learn
    finally:
        load.stop()
        watcher.close()
        procs.close()
        broker.stop()


def test_run_share_says_what_it_needs() -> None:
    """`run --share` on an in-process bus is refused in one line, before anything starts; with --discover it is
    taken (each robot the graph shows goes to one of the processes that see it): here it goes on to the package."""
    from tests.conftest import EXAMPLE

    base = [sys.executable, "-m", "td2adaptor", "run", str(EXAMPLE / "td.json"), "-I", str(EXAMPLE / "interfaces")]
    local = subprocess.run([*base, "--robot", "r1", "--share"], capture_output=True, text=True, timeout=120)
    assert local.returncode == 1 and "--share needs one MQTT bus for the whole fleet" in local.stderr, local.stderr
    both = subprocess.run(
        [*base, "--robot", "r1", "--bus", "mqtt://127.0.0.1:1", "--share", "--discover"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert both.returncode == 1 and "cannot import the adaptor package" in both.stderr, both.stderr
    assert "Traceback" not in local.stderr + both.stderr


def test_a_process_that_hangs_is_noticed_by_its_keepalive_and_rejoins_without_a_fight(tmp_path: Path) -> None:
    """SIGSTOP: the process's connections stay open, as when its host or network is gone, so only the member
    connection's keepalive tells (1.5 x share_keepalive = 3 s, then the will): its robots are served again
    within 5 s. SIGCONT: it finds its robots' sessions taken, lets them go, and takes a share again by hand-over;
    in the end each robot has one owner and no mission ran twice."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    robots = 10
    procs = Procs(broker, tmp_path, robots)
    watcher = Watcher(broker)
    load = Load(broker, [f"rb_{i:02d}" for i in range(robots)])
    try:
        started = procs.start_many(2)
        pids = {p.pid for p in started}
        assert until(lambda: served_by(watcher, pids, robots) and set(shares(watcher, pids).values()) == {5}, 60)
        load.start()
        time.sleep(2)
        frozen, other = started
        theirs = [r for r, (_s, pid) in watcher.owners().items() if pid == frozen.pid]
        stopped = time.monotonic()
        frozen.send_signal(signal.SIGSTOP)
        try:
            assert until(lambda: served_by(watcher, {other.pid}, robots), 20), (watcher.owners(), procs.logs())
            back = {
                robot: t - stopped
                for t, robot, p in reversed(list(watcher.statuses()))
                if robot in theirs and t > stopped and p.get("state") == "online" and p["owner"]["pid"] == other.pid
            }
            print(f"a hung process's robots served again after {min(back.values()):.2f}-{max(back.values()):.2f} s")
            # share_timeout (3 s) after its last beat, which came up to a beat period (0.75 s) before the stop
            assert len(back) == 5 and 2.25 <= min(back.values()) and max(back.values()) <= 5.0, back
        finally:
            frozen.send_signal(signal.SIGCONT)
        assert until(lambda: served_by(watcher, pids, robots) and set(shares(watcher, pids).values()) == {5}, 30), (
            watcher.owners(),
            procs.logs(),
        )
        time.sleep(2)
        load.stop()
        # every invoke is answered, also one the hung process had read just before it froze (it acknowledges a
        # command only once admitted: the broker gave it to the other process)
        every_invoke_answered(load, watcher, procs)
        assert max(procs.runs_of().values()) == 1
        ends = watcher.terminals()
        assert all(len({(p["state"], p.get("seq")) for p in ends[i]}) == 1 for i in load.sent)
        members = retained(broker, "td2adaptor/.fleet/shared/members/+")
        records = [e for e in members.values() if e.get("owner")]
        assert sorted(r for rec in records for r in rec["robots"]) == [f"rb_{i:02d}" for i in range(robots)]
    finally:
        load.stop()
        watcher.close()
        procs.close()
        broker.stop()
