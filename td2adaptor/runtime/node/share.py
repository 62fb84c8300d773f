"""Several edge-node processes share one fleet, coordinated through the broker (`run --share`, docs/fleet.md).

Why the broker: it is the one thing every process already trusts and reaches, so no cluster of our own is
needed. Three MQTT features carry it (docs/brokers.md): retained messages, the last will, and one session per
client id.

* **Members.** Each process keeps a retained record on `<root>/.fleet/<fleet>/members/<node>` (its owner
  record, the robots it serves, the last takeovers) on a connection of its own whose will is the empty
  retained message there: when the process dies the broker clears its record, at once when the socket closes
  (a killed process: the kernel closes it). When its host or network is gone the broker learns it only from
  the keepalive, late (1.5 x keepalive, and mosquitto 2.0 looks only every 6 s), so each member also beats
  (`<root>/.fleet/<fleet>/beats/<node>`, QoS 0, every `timeout` / 4) and one silent for `timeout` is taken
  as gone by the others, by their own clocks.
* **Who serves which robot.** Every process reads the same candidates (the fleet file's robots) and the same
  members, and computes the same answer (`assign`: rendezvous hashing with a bound on the load, so the shares
  differ by one robot at most and a member that leaves moves little but its own robots).
* **Hand-over.** A robot whose owner is no longer the one `assign` names is released by that owner first:
  its missions in flight end with a terminal event that names the next owner, its TD stays retained, and its
  status stays `online` with `handover` naming the next owner (no `offline` blip). The next owner claims it
  only once the robot's retained status says it is free: handed over to it, `offline`, or owned by a process
  that is no longer a member (it died). A robot's commands wait meanwhile in its persistent MQTT session.
* **No command twice.** The new owner takes the robot's MQTT session (the same client id), so a command the
  dead owner had received but not acknowledged is delivered to it again; the robot's replay guard and mission
  ledger (state_dir, engine/replay.py and ledger.py) answer a command id seen before instead of running it,
  and follow the dead owner's missions in flight again or end them, with one terminal event each. Across hosts,
  which do not share a state directory, the owner publishes what it admitted on the broker and the next owner
  learns it before it serves (node/admitted.py).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from datetime import datetime, timezone
from functools import partial
from typing import Any

import orjson

from td2adaptor.runtime.bus.bus import Bus, Message, round_trip
from td2adaptor.runtime.config import ConfigError, RuntimeConfig
from td2adaptor.runtime.engine.engine import Engine, status_event
from td2adaptor.runtime.node.admitted import (
    AckedPort,
    Book,
    Recorder,
    RecordingGuard,
    RecordingLedger,
    admitted_topic,
    seed,
)
from td2adaptor.runtime.node.fleet import Changes, Fleet, FleetError
from td2adaptor.runtime.node.owner import Owner, lives, this_process
from td2adaptor.runtime.node.shareplan import (
    Status,
    assign,
    beats_topic,
    entries_topic,
    members_topic,
    names,
    orphaned,
    read_status,
)

log = logging.getLogger("td2adaptor.runtime.share")

#: the origin of shared robots in the fleet (node/fleet.py): they come from the fleet file
ORIGIN = "file"
#: takeovers a member record keeps (`fleet status` shows them)
TAKEOVERS_KEPT = 20
#: seconds a robot handed over to another live member waits for it, from when this process found it is its own;
#: then this process takes it (the member it was handed over to learnt meanwhile that it is no longer its: another
#: member joined). Two claims at once are settled by the broker: the robot's session is taken over, and the
#: process that lost it lets the robot go (`_lost`)
HANDOVER_WAIT = 5.0
#: seconds between two sweeps of the admitted invokes no copy of which could still be fresh (admitted.py)
SWEEP_PERIOD = 10.0
#: what a robot's bus says when another connection took its session over (owner.taken_by, mqttbus.py)
TAKEN_OVER = "took its session over"
#: seconds a robot newly listed by a member (the fleet file read again, a robot discovered, an admin request) waits
#: before it is given out: the members that list it a moment later (they read the file or look at the ROS graph
#: a little after) are known by then, so every member computes the same owner and the robot is not handed on.
#: A robot a member's discovery found waits less when every live member has said whether it sees it (`_heard`)
SETTLE = 0.75
#: seconds after it learnt that another member's discovery found a robot a member says (`unseen`) that its own
#: discovery does not show it: the graphs of two processes show a robot that appears a moment apart (their ROS 2
#: discovery), so the first look, at once, shows it only when the graph has it already
UNSEEN_AFTER = 0.25
#: seconds a robot its owner retired (it no longer lists it) waits before another member that still lists it claims
#: it: the other members drop it too a moment later (they read the file, or look at the graph, a little after)
RETIRED_WAIT = 2.0
#: seconds a robot this process handed over, and which nobody took, may be listed by no live member before this
#: process retires it (`_unclaimed`): the member it was handed over to dropped it before it took it, and so did
#: every other one (node/unclaimed.py)
UNCLAIMED_WAIT = RETIRED_WAIT


def _now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")[:-4] + "Z"


class Share:
    """This process's part in a shared fleet: keeps its member record, watches the other members and the
    robots' statuses, and makes `fleet` serve exactly the robots `assign` gives it (see the module docstring).

    `bus` is an unconnected bus of this process's own (`share_bus`); its will must clear the member record.
    Changes run on a thread of their own, never on the bus's thread (a robot's connection needs that thread)."""

    def __init__(
        self,
        fleet: Fleet,
        bus: Bus,
        *,
        name: str,
        root: str,
        settle: float = 1.0,
        timeout: float = 3.0,
        me: Owner | None = None,
        make_config: Callable[[str, str | None], RuntimeConfig] | None = None,
    ) -> None:
        self.fleet = fleet
        self.bus = bus
        self.name = name
        self.root = root
        self.settle = settle  # seconds to wait at start for members that start at the same moment
        self.timeout = timeout  # seconds a member may be silent (no beat) before the others take its robots
        self.me = me or this_process()
        fleet.check = _no_check  # who may serve a robot is decided here, from the members and the statuses
        fleet.source = lambda robot, _origin: f"shared, {self.origin(robot) or 'listed by another member'}"
        self.takeovers: deque[dict[str, Any]] = deque(maxlen=TAKEOVERS_KEPT)
        self.on_change: list[Callable[[Changes], None]] = []  # tests, logs: after each change of the share
        self._lock = threading.Lock()
        self._members: dict[str, dict[str, Any]] = {}  # node -> its record
        self._gone: set[str] = set()  # members whose record was cleared (they stopped or died)
        self._beats: dict[str, float] = {}  # node -> when it last beat (time.monotonic(), by this process's clock)
        self._beat_at = time.monotonic()  # when this process's beat thread last ran (`_stood_still`)
        self._silent: set[str] = set()  # members taken as gone because they stopped beating
        self._statuses: dict[str, Status] = {}  # robot -> its retained status
        self._retired_at: dict[str, float] = {}  # robot -> when its status said it was retired (`RETIRED_WAIT`)
        self._candidates: dict[str, RuntimeConfig] = {}  # the fleet file's robots
        self.make_config = make_config  # (robot, namespace) -> its settings: the robots discovery or the admin adds
        self._found: dict[str, RuntimeConfig] = {}  # the robots this process's discovery sees (graphwatch.py)
        self._admin: dict[str, RuntimeConfig] = {}  # the robots admin requests added (retained entries, admin.py)
        self._cleared: set[str] = set()  # entries this process published that another one cleared (`_forget`)
        self._first: dict[str, float] = {}  # robot -> since when a member lists it (`SETTLE`)
        self._listers: dict[str, set[str]] = {}  # robot -> the live members that listed it at the last plan
        #: robot -> (live members that stopped listing it, since when): still counted as listing it (`_hold`)
        self._held: dict[str, tuple[set[str], float]] = {}
        self._planned = False  # a first plan was made (what is listed at the start is given out at once)
        self._due: float | None = None  # when the next robot waiting for `SETTLE` is given out
        self._wake = threading.Event()
        self._changing = threading.RLock()  # one reconciliation at a time (the share's thread, a reload)
        self._waiting: dict[str, float] = {}  # robot -> since when it is ours but handed over to another member
        #: robot -> (its settings, since when no live member lists it): handed over by this process, not taken yet
        self._handed: dict[str, tuple[RuntimeConfig, float]] = {}
        #: robot -> since when it is "online, handed over" by a member that left (died) and no live member lists it:
        #: this process retires it if it is the one to (`_orphans`); None: it tried and could not
        self._orphaned: dict[str, float | None] = {}
        self._listed: set[str] = set()  # what the live members list, at the last plan
        #: robot -> when this process learnt that another member's discovery found it, which this one did not
        self._asked: dict[str, float] = {}
        self._unseen: set[str] = set()  # of those, the ones this process's discovery looked for and did not see
        self._foreign: set[str] = set()  # robots served by a live process outside the share: logged once each
        self._look_now: Callable[..., None] | None = None  # this process's discovery, to look at once (`follow`)
        self._graph = ""  # which ROS graph its discovery reads (graphwatch.py `Graph.name`; "": unknown)
        self._taken: set[str] = set()  # robots whose session another member took: let go at the next round
        #: robots this process is starting (its record says so: `_free`, `_admit`), from the claim to the end of their
        #: start (`_start`): of every set whose start is under way, several at once (`_begin`)
        self._starting: set[str] = set()
        self._leaving: set[str] = set()  # robots this process hands over or retires now (`_let_go`)
        self._starts: set[threading.Thread] = set()  # the starts and hand-overs under way (`stop` waits for them)
        self._recording = threading.Lock()  # one record built and published at a time: the last built is the last sent
        fleet.on_added.append(self._watch)
        fleet.prepare = self._prepare
        fleet.admit = self._admit
        self.book = Book()  # every robot's admitted invokes, as the broker has them
        self._swept = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._joined = _now()
        self._last_record = b""
        self._entries_mine: set[str] = set()  # entry topics this process published (`_forget`)

    # -- the fleet file's side (node/fleetfile.py calls `apply` as it calls Fleet.apply) --------------------

    def apply(self, configs: Sequence[RuntimeConfig], origin: str = ORIGIN) -> Changes:
        """New candidates (the fleet file read again): this process serves its share of them. From discovery
        (origin "discovery", graphwatch.py): the robots this process sees, which the share gives out among the
        members that see them."""
        if origin == "discovery":
            return self._see(configs)
        after = {c.robot: c for c in configs}
        with self._lock:
            before, self._candidates = self._candidates, after
        try:
            changes = self.reconcile()
        finally:
            self._wake.set()  # a robot just listed is given out once it settled
        changes.listed = sorted(set(after) - set(before) - set(changes.added))
        changes.unlisted = sorted(set(before) - set(after) - set(changes.removed))
        return changes

    def robots(self, origin: str | None = None) -> dict[str, RuntimeConfig]:
        """The robots this process lists (of one origin): what discovery compares its look with."""
        with self._lock:
            sources = {"file": self._candidates, "admin": self._admin, "discovery": self._found}
            if origin is not None:
                return dict(sources.get(origin, {}))
            return self._mine()

    def origin(self, robot: str) -> str | None:
        with self._lock:
            for origin, source in (("file", self._candidates), ("admin", self._admin), ("discovery", self._found)):
                if robot in source:
                    return origin
        return None

    def _see(self, configs: Sequence[RuntimeConfig]) -> Changes:
        with self._lock:
            seen = {c.robot: c for c in configs}
            came, went = sorted(set(seen) - set(self._found)), sorted(set(self._found) - set(seen))
            self._found = seen
        for words, robots in (("sees", came), ("no longer sees", went)):
            if robots:
                log.info("fleet %s: this process %s %s in the ROS graph", self.name, words, ", ".join(robots))
        self._publish_record()  # the other members learn what this one can serve
        self._wake.set()
        return Changes()  # who serves them is decided by the share's next round

    def follow(self, discovery: Any) -> None:
        """This process discovers robots (graphwatch.py `Discovery`): when another member finds a robot this one
        does not list, its discovery looks at once, and after a look that began `UNSEEN_AFTER` later, this process
        says in its record that it does not see it (`unseen`): the robot is given out once every live member said
        whether it sees it (`_heard`) rather than after the whole `SETTLE`."""
        self._look_now = discovery.look_now
        self._graph = discovery.graph.name
        discovery.on_look.append(self._looked)

    def _looked(self, began: float) -> None:
        """(discovery's thread) A look at the graph that began at `began` is done: what the others found that it
        did not show is `unseen` now."""
        with self._lock:
            mine = self._mine()
            unseen = self._unseen | {r for r, t in self._asked.items() if t + UNSEEN_AFTER <= began and r not in mine}
            changed = unseen != self._unseen
            self._unseen = unseen
        if changed:
            self._publish_record()
            self._wake.set()

    def _mine(self) -> dict[str, RuntimeConfig]:
        """(under the lock) The robots this process can serve: its file's, the admin's, what it sees."""
        return {**self._found, **self._admin, **self._candidates}

    # -- what admin requests ask (admin.py) ----------------------------------------------------------------

    def live(self) -> set[str]:
        """The members taken as live now, this one included."""
        with self._lock:
            return self._live()

    def listed(self) -> set[str]:
        """Every robot some live member lists (its file, its discovery, the admin's)."""
        with self._lock:
            live = self._live()
            out = set(self._mine())
            for node, record in self._members.items():
                if node in live:
                    out.update(record.get("can") or ())
            return out

    def unseen(self) -> set[str]:
        """The robots another member's discovery found that this process looked for and does not see."""
        with self._lock:
            return set(self._unseen)

    def starting(self) -> set[str]:
        """The robots this process claimed and is starting now."""
        with self._lock:
            return set(self._starting)

    def admin_robots(self) -> set[str]:
        with self._lock:
            return set(self._admin)

    def status(self, robot: str) -> Status | None:
        """The robot's retained status as this process last read it."""
        with self._lock:
            return self._statuses.get(robot)

    def record(self, node: str) -> Mapping[str, Any] | None:
        with self._lock:
            return self._members.get(node)

    # -- life cycle ----------------------------------------------------------------------------------------

    def start(self, candidates: Sequence[RuntimeConfig]) -> None:
        """Join: read the members and statuses, publish our record, wait `settle`, take our share."""
        self._candidates = {c.robot: c for c in candidates}
        self.bus.subscribe(members_topic(self.root, self.name), self._on_member)
        self.bus.subscribe(f"{self.root}/+/status", self._on_status)
        self.bus.subscribe(admitted_topic(self.root, self.name), self.book.take)
        self.bus.subscribe(beats_topic(self.root, self.name), self._on_beat)
        self.bus.subscribe(entries_topic(self.root, self.name), self._on_entry)
        self.bus.connect()
        self.bus.subscribe(f"{members_topic(self.root, self.name)}/+", lambda _m: None)  # the retained ones are in
        self._publish_record()
        self._beat_at = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="td2adaptor-share", daemon=True)
        self._thread.start()
        self._beater = threading.Thread(target=self._beat, name="td2adaptor-share-beat", daemon=True)
        self._beater.start()

    def stop(self) -> None:
        """Leave: no more changes; each robot is handed over to the member that serves it without this process
        (no `offline` in between), then the record is cleared. Alone, the robots go offline with the fleet."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(30)
        with self._lock:
            starts = list(self._starts)
        for start in starts:  # what they start is served, then handed over below
            start.join(30)
        with self._changing:
            with self._lock:
                plan, _mine = self._plan(self._live() - {self.me.node})
            for robot in self.fleet.robots(ORIGIN):
                if plan.get(robot) is not None:
                    self._release(robot, plan[robot])
        try:
            self.bus.publish(members_topic(self.root, self.name, self.me.node), b"", retain=True)
            self.bus.flush(5)
        except Exception:  # noqa: BLE001 - leaving: the will clears it when the connection closes uncleanly
            log.warning("could not clear this process's member record")
        self.bus.close()

    def members(self) -> dict[str, dict[str, Any]]:
        with self._lock:
            return dict(self._members)

    # -- what the broker tells (the bus's thread: only record and wake) ----------------------------------

    def _on_member(self, message: Message) -> None:
        node = message.topic.rsplit("/", 1)[1]
        new: list[str] = []  # robots its discovery found that this process does not list
        with self._lock:
            if not message.payload:
                if self._members.pop(node, None) is not None:
                    log.info("fleet %s: member %s left", self.name, node)
                self._gone.add(node)
            else:
                try:
                    record = orjson.loads(message.payload)
                except orjson.JSONDecodeError:
                    return
                if not isinstance(record, dict):
                    return
                if node not in self._members:
                    log.info("fleet %s: member %s joined", self.name, node)
                    # a `timeout` of grace for its first beat, also when it rejoins (its beats before it left are
                    # stale: it was taken as gone at once, until its next beat)
                    self._beats[node] = time.monotonic()
                self._members[node] = record
                self._gone.discard(node)
                mine = self._mine()
                new = [r for r in names(record.get("found")) if r not in mine and r not in self._asked]
                self._asked.update(dict.fromkeys(new, time.monotonic()))
        if new and self._look_now is not None:
            self._look_now(UNSEEN_AFTER)  # does this process see them too? (`_heard`)
        self._wake.set()

    def _on_status(self, message: Message) -> None:
        robot = message.topic.split("/")[-2]
        status = read_status(message.payload) if message.payload else None
        with self._lock:
            if status is None:
                self._statuses.pop(robot, None)
            else:
                self._statuses[robot] = status
            if status is not None and status.retired:
                self._retired_at.setdefault(robot, time.monotonic())
            else:
                self._retired_at.pop(robot, None)
        self._wake.set()

    def _on_entry(self, message: Message) -> None:
        """A robot added by an admin request (its retained entry), or removed (the entry cleared)."""
        robot = message.topic.rsplit("/", 1)[1]
        config: RuntimeConfig | None = None
        if message.payload and self.make_config is not None:
            try:
                entry = orjson.loads(message.payload)
                namespace = entry.get("namespace") if isinstance(entry, dict) else None
                config = self.make_config(robot, namespace if isinstance(namespace, str) else None)
            except (orjson.JSONDecodeError, ConfigError) as exc:
                log.error("fleet %s: the admin's entry of robot %s cannot be served: %s", self.name, robot, exc)
        with self._lock:
            if config is None:
                if self._admin.pop(robot, None) is not None:
                    self._cleared.add(message.topic)
            else:
                self._admin[robot] = config
        self._wake.set()

    def _on_beat(self, message: Message) -> None:
        node = message.topic.rsplit("/", 1)[1]
        with self._lock:
            self._beats[node] = time.monotonic()
            back = node in self._silent
        if back:
            self._wake.set()

    def _beat(self) -> None:
        """(a thread of its own, so that a long change does not silence this process) Beat every timeout / 4."""
        topic = beats_topic(self.root, self.name, self.me.node)
        while not self._stop.wait(self.timeout / 4):
            with self._lock:
                self._stood_still()
                self._beat_at = time.monotonic()
            try:
                self.bus.publish(topic, b"{}", qos=0)  # JSON, as everything else under the root
            except Exception:  # noqa: BLE001 - not connected now: the others may take this process as gone
                log.debug("fleet %s: beat not sent", self.name)

    def _stood_still(self) -> None:
        """(under the lock) This process stood still (SIGSTOP, a hung host) longer than `timeout` (its beat thread
        did not run): the others' beats sent meanwhile wait unread in its socket, so their silence is its own.
        Each member gets a `timeout` of grace from now, as at its first beat, rather than its robots taken."""
        now = time.monotonic()
        if now - self._beat_at > self.timeout:
            log.warning("fleet %s: this process stood still for %.1f s", self.name, now - self._beat_at)
            self._beats = dict.fromkeys(self._beats, now)
            self._beat_at = now

    def _live(self) -> set[str]:
        """(under the lock) The members whose record is there and that beat within `timeout`, and this one."""
        self._stood_still()
        now = time.monotonic()
        live = {n for n in self._members if now - self._beats.get(n, now) <= self.timeout}
        for node in set(self._members) - live - self._silent:
            log.warning("fleet %s: member %s sent no beat for %g s: taken as gone", self.name, node, self.timeout)
        for node in self._silent & live:
            log.info("fleet %s: member %s beats again", self.name, node)
        self._silent = set(self._members) - live
        return live | {self.me.node}

    # -- the share's own thread ----------------------------------------------------------------------------

    def _run(self) -> None:
        if self._stop.wait(self.settle):  # members that start at the same moment see each other first
            return
        while not self._stop.is_set():
            self._wake.clear()
            try:
                with self._changing:
                    self._reconcile()  # what it claims starts on a thread of its own, which wakes this one at its end
                self._sweep()
                self._forget()
            except Exception:  # one failed round must not end the share: the next wake tries again
                log.exception("fleet %s: sharing the robots failed", self.name)
            wait = min(1.0, self.timeout / 4)  # also: a member that went silent
            due = self._due
            if due is not None:  # a robot that settles meanwhile
                wait = max(0.01, min(wait, due - time.monotonic()))
            self._wake.wait(wait)

    def reconcile(self) -> Changes:
        """Release what is no longer ours (hand-over), then claim what is ours and free; returns once the robots it
        claimed are started (the share's own thread does not wait for that: `_run`)."""
        with self._changing:
            changes, start, started = self._reconcile()
        if start is not None:
            start.join()
            changes.added += started.added
            changes.replaced += started.replaced
            changes.failed.update(started.failed)
        return changes

    def _plan(self, live: set[str]) -> tuple[dict[str, str], dict[str, RuntimeConfig]]:
        """(under the lock) Who serves which robot among `live`, each robot among the members that list it (their
        records' `can`; this process's own lists, fresher), and the robots this process can serve. A robot newly
        listed waits `SETTLE` (`_due` says until when), except at the first plan."""
        now = time.monotonic()
        mine = self._mine()
        can = self._lists(live, mine)
        listed = set().union(*can.values()) if can else set()
        self._listed = listed
        can = self._hold(can, live, now)
        held = set().union(*can.values()) - listed
        self._first = {r: self._first.get(r, now if self._planned else 0.0) for r in listed | held}
        self._planned = True
        found = self._found_by(live)
        self._asked = {r: t for r, t in self._asked.items() if r in found and r not in mine}
        self._unseen = set(self._asked) if self._look_now is None else self._unseen & set(self._asked)
        ready = {r for r, t in self._first.items() if now - t >= SETTLE or self._heard(r, live, can, found)}
        waiting = [t + SETTLE for r, t in self._first.items() if r not in ready]
        waiting += [since + SETTLE for _members, since in self._held.values()]
        self._due = min(waiting) if waiting else None
        return assign(ready, live, can), mine

    def _hold(self, can: dict[str, set[str]], live: set[str], now: float) -> dict[str, set[str]]:
        """(under the lock) `can`, with each robot a live member stopped listing less than `SETTLE` ago still
        listed by it: a removal settles like an addition. The members stop listing a robot each at its own moment
        (they read the file, the admin's entry or their ROS graph a little apart), and each removal changes the
        bound of the plan at once: an unrelated robot went from one member to the other at the first and back at
        the second, 80 ms later (issue 32). Held, the plan changes once, when the last removal settled. A member
        that left is not waited for (its robots are taken over at once). The robot's owner, if it no longer lists
        it, retires it at once all the same (`_reconcile`)."""
        listers: dict[str, set[str]] = {}
        for member, robots in can.items():
            for robot in robots:
                listers.setdefault(robot, set()).add(member)
        held: dict[str, tuple[set[str], float]] = {}
        for robot in set(self._listers) | set(self._held):
            members, since = self._held.get(robot, (set(), now))
            dropped = (self._listers.get(robot, set()) - listers.get(robot, set())) & live if self._planned else set()
            if dropped:
                members, since = members | dropped, now
            members = members & (live - listers.get(robot, set()))
            if members and now - since < SETTLE:
                held[robot] = (members, since)
        self._held = held
        self._listers = listers
        out = {member: set(robots) for member, robots in can.items()}
        for robot, (members, _since) in held.items():
            for member in members:
                out.setdefault(member, set()).add(robot)
        return out

    def _found_by(self, live: set[str]) -> set[str]:
        """(under the lock) The robots the discovery of a live member (this one included) finds."""
        found = set(self._found)
        for node in live - {self.me.node}:
            found.update(names(self._members.get(node, {}).get("found")))
        return found

    def _heard(self, robot: str, live: set[str], can: Mapping[str, set[str]], found: set[str]) -> bool:
        """(under the lock) May `robot`, newly listed, be given out before `SETTLE` is over? Yes when a member's
        discovery found it and every live member said whether it sees it: it lists it, or it looked at its graph
        since it learnt of it and did not see it (`unseen`; a member without discovery at once), or it reads
        another ROS graph than every member that found it (another ROS 2 domain, ROS 1 master: `graph` in its
        record), which cannot show it. Then no member that sees it is left out of the plan. A robot of a fleet
        file or an admin request waits the whole `SETTLE`: the members read a reloaded file, or an entry, each at
        its own moment and say nothing before."""
        if robot not in found or robot in self._admin:
            return False
        graphs = {self._graph_of(n) for n in live if robot in self._found_of(n)}
        for node in live:
            if robot in can.get(node, ()):
                continue
            unseen = self._unseen if node == self.me.node else names(self._members.get(node, {}).get("unseen"))
            elsewhere = "" not in graphs and self._graph_of(node) not in graphs | {""}
            if robot not in unseen and not elsewhere:
                return False
        return True

    def _graph_of(self, node: str) -> str:
        """(under the lock) Which ROS graph member `node`'s discovery reads ("": unknown, or none)."""
        if node == self.me.node:
            return self._graph
        graph = self._members.get(node, {}).get("graph")
        return graph if isinstance(graph, str) else ""

    def _found_of(self, node: str) -> set[str]:
        """(under the lock) What member `node`'s discovery finds."""
        return set(self._found) if node == self.me.node else names(self._members.get(node, {}).get("found"))

    def _lists(self, live: set[str], mine: Mapping[str, RuntimeConfig]) -> dict[str, set[str]]:
        """(under the lock) Member -> the robots it lists, of the `live` ones (this one: `mine`)."""
        admin = set(self._admin)  # every member can serve these: the entries, not the records, say which
        can = {m: set(self._members.get(m, {}).get("can") or ()) | admin for m in live if m != self.me.node}
        if self.me.node in live:
            can[self.me.node] = set(mine)
        return can

    def _reconcile(self) -> tuple[Changes, threading.Thread | None, Changes]:
        """(under `_changing`) One round: the changes made, and the start of the robots claimed (`_begin`), under
        way, with what it will have done. A robot whose start is under way is left alone (neither claimed again
        nor handed over): the round its end wakes looks at it."""
        with self._lock:
            busy = self._starting | self._leaving  # before `served`: a start that ends meanwhile registered them first
            live = self._live()
            plan, candidates = self._plan(live)
            statuses = dict(self._statuses)
            gone = self._gone | self._silent
            listed = set(self._listed)
        self._publish_record()  # what this process can serve, when that changed (the others' plans need it)
        with self._lock:
            lost, self._taken = self._taken, set()
        for robot in lost:  # another member holds its session now: its status is that member's, not ours to touch
            self.fleet.remove(robot, "was taken over by another process of the fleet")
        served = self.fleet.robots(ORIGIN)
        changes = Changes()
        leaving: dict[str, str | None] = {}  # robot -> the member it is handed over to (None: retired)
        for robot in served:
            if robot in busy:
                continue
            winner = plan.get(robot) if robot in candidates else None  # no longer listed here: retired, not handed on
            if winner != self.me.node:
                leaving[robot] = winner
        claims: list[RuntimeConfig] = []
        taken: list[tuple[str, Status | None]] = []
        replaced: list[str] = []
        for robot, config in candidates.items():
            if plan.get(robot) != self.me.node or robot in busy:
                continue
            if robot in served and robot not in leaving:
                if served[robot] != config:  # its settings changed (the fleet file read again): it restarts
                    claims.append(config)
                    replaced.append(robot)
                continue
            status = statuses.get(robot)
            if self._free(robot, status, live, gone):
                claims.append(config)
                taken.append((robot, status))
        self._waiting = {r: t for r, t in self._waiting.items() if plan.get(r) == self.me.node and r not in served}
        if self._stop.is_set():  # leaving (a reload's round after `stop`): nothing more is started
            claims = []
        start, started = self._begin(claims, taken, replaced) if claims else (None, Changes())
        if leaving:  # once the claimed robots' start began
            self._let_go(leaving)
            changes.removed += leaving
        for config in self._unclaimed(statuses, listed, set(self.fleet.robots(ORIGIN))):
            if self._retire_unclaimed(config):
                changes.removed.append(config.robot)
        for config in self._orphans(statuses, listed, live):
            if self._retireorphaned(config):
                changes.removed.append(config.robot)
        self._changed(changes)
        return changes, start, started

    def _begin(
        self, claims: list[RuntimeConfig], taken: list[tuple[str, Status | None]], replaced: list[str]
    ) -> tuple[threading.Thread, Changes]:
        """Start `claims` on a thread of their own (`_start`), so that the next round claims and starts other robots,
        and hands robots over, while this start is under way (issue 32: a robot claimed during a start waited for
        its end, 0.2-1 s on a loaded machine). Its record says `starting` first: the others leave them to this
        process meanwhile (`_free`, `_admit`)."""
        robots = {c.robot for c in claims}
        with self._lock:
            self._starting |= robots
        self._publish_record()
        started = Changes()
        work = partial(self._start, claims, taken, replaced, started)
        thread = self._aside(
            "td2adaptor-share-start", work, self._starting, robots, then=partial(self._changed, started)
        )
        return thread, started

    def _let_go(self, leaving: dict[str, str | None]) -> None:
        """Hand `leaving` over (or retire them, None) on a thread of their own (`_release`): each robot's stop (its
        last status acknowledged, its port closed) took 0.1-0.6 s on a loaded machine, and a robot found ready
        meanwhile waited for the next round. Until they are stopped they are left alone (`_reconcile`: `busy`)."""
        with self._lock:
            self._leaving |= set(leaving)

        def run() -> None:
            for robot, winner in leaving.items():
                try:
                    self._release(robot, winner)
                except Exception:  # noqa: BLE001 - the others are let go all the same
                    log.exception("fleet %s: letting robot %s go failed", self.name, robot)

        self._aside("td2adaptor-share-release", run, self._leaving, set(leaving))

    def _aside(
        self,
        name: str,
        work: Callable[[], None],
        marked: set[str],
        robots: set[str],
        then: Callable[[], None] | None = None,
    ) -> threading.Thread:
        """Run `work` (a start or a hand-over) on a thread of its own that `stop` waits for; at its end `robots`
        leave `marked` (`_starting`, `_leaving`: left alone by the rounds until then), the record says so, a
        round of the share looks at them, then `then()`."""

        def run() -> None:
            try:
                work()
            finally:
                with self._lock:
                    marked.difference_update(robots)
                    self._starts.discard(threading.current_thread())
                self._publish_record()
                self._wake.set()
            if then is not None:
                then()

        thread = threading.Thread(target=run, name=name, daemon=True)
        with self._lock:
            self._starts.add(thread)
        thread.start()
        return thread

    def _start(
        self, claims: list[RuntimeConfig], taken: list[tuple[str, Status | None]], replaced: list[str], out: Changes
    ) -> None:
        """(a start's thread, `_aside`) Start `claims` (the `replaced` ones stopped first: their settings changed);
        what it did goes into `out`, which the log and the hooks hear of once the record says so (`_begin`)."""
        robots = {c.robot for c in claims}
        try:
            for robot in replaced:
                self.fleet.remove(robot, "restarts with changed settings")
            try:
                changes = self.fleet.join(claims, ORIGIN)
            except FleetError as exc:  # the edge node is stopping
                changes = Changes(failed=dict.fromkeys(robots, exc.why))
            for robot, status in taken:
                if robot in changes.added:
                    self._took(robot, status)
            out.replaced = [r for r in replaced if r in changes.added]
            out.added = [r for r in changes.added if r not in replaced]
            out.failed = changes.failed
        except Exception:  # noqa: BLE001 - the next round claims what was not started
            log.exception("fleet %s: starting %s failed", self.name, ", ".join(sorted(robots)))

    def _changed(self, changes: Changes) -> None:
        if changes:
            log.info("fleet %s: %s", self.name, changes.describe())
            self._publish_record()
            for hook in list(self.on_change):
                hook(changes)

    def _unclaimed(self, statuses: Mapping[str, Status], listed: set[str], served: set[str]) -> list[RuntimeConfig]:
        """The robots this process handed over that are still "online, handed over" by it, and that no live
        member has listed for `UNCLAIMED_WAIT`: the member it was handed over to dropped it before it took it,
        and nobody else will take it. A robot taken (its status another's, or `offline`) or served here again is
        forgotten; one listed again is left to the member that lists it."""
        now = time.monotonic()
        due: list[RuntimeConfig] = []
        with self._lock:
            for robot, (config, since) in list(self._handed.items()):
                if robot in self._leaving:  # its hand-over still stops it (`_let_go`): served here until then
                    continue
                status = statuses.get(robot)
                if not _still_handing(status, self.me.node) or robot in served:
                    del self._handed[robot]
                elif robot in listed:
                    self._handed[robot] = (config, now)
                elif now - since >= UNCLAIMED_WAIT:
                    due.append(config)
        return due

    def _retire_unclaimed(self, config: RuntimeConfig) -> bool:
        """Retire a robot nobody took (`_unclaimed`) on its own session, as it would be retired here: `offline`
        with `retired`, TD cleared (node/unclaimed.py). Looked at once more first: a member that lists it now
        claims it only `SETTLE` after it listed it, long after its record came here."""
        from td2adaptor.runtime.bus.bus import BusError
        from td2adaptor.runtime.node.status import owner_fields
        from td2adaptor.runtime.node.unclaimed import retire

        robot = config.robot
        with self._lock:
            listed = set().union(*self._lists(self._live(), self._mine()).values())
            status = self._statuses.get(robot)
            if robot in listed or not _still_handing(status, self.me.node):
                self._handed.pop(robot, None)
                return False
            to = status.handover if status is not None else None
        retired = {"node": self.me.node, "time": _now()}
        offline = status_event(config, self.fleet.model, "offline", **owner_fields(), retired=retired)
        try:
            done = retire(config, self.fleet.model, offline)
        except BusError as exc:
            done = False
            log.warning("robot %s: could not retire it: %s", robot, exc)
        with self._lock:
            if done:
                self._handed.pop(robot, None)
            elif robot in self._handed:
                self._handed[robot] = (config, time.monotonic())  # again after UNCLAIMED_WAIT
        if done:
            log.info(
                "robot %s: retired: handed over to member %s, which dropped it before it took it, and no member "
                "lists it",
                robot,
                to,
            )
        return done

    def _orphans(self, statuses: Mapping[str, Status], listed: set[str], live: set[str]) -> list[RuntimeConfig]:
        """The robots a member that left (it died: its record was cleared) had handed over, still "online, handed
        over" by it, that no live member has listed for `UNCLAIMED_WAIT`: the member it was handed over to dropped
        it, and the one that handed it over died before it retired it (`_unclaimed`). The member it was handed to
        retires it if it is live, else the live member whose node id sorts first: the same one in every view.
        Its settings are the template's (`make_config`): the robot's credentials, where the fleet's robots share
        the top-level user; one the broker refuses is left as it is (said once in the log)."""
        if self.make_config is None:
            return []
        now = time.monotonic()
        due: list[RuntimeConfig] = []
        with self._lock:
            for robot in set(self._orphaned) - set(statuses):
                del self._orphaned[robot]
            for robot, status in statuses.items():
                if not orphaned(status, self._left(status), live) or robot in listed:
                    self._orphaned.pop(robot, None)
                    continue
                to = status.handover or ""  # set: `_orphan`
                if (to if to in live else min(live)) != self.me.node:
                    continue
                since = self._orphaned.setdefault(robot, now)
                if since is not None and now - since >= UNCLAIMED_WAIT:
                    try:
                        due.append(self.make_config(robot, None))
                    except ConfigError as exc:
                        log.warning("robot %s: could not retire it: %s", robot, exc)
                        self._orphaned[robot] = None
        return due

    def _left(self, status: Status) -> set[str]:
        """(under the lock) The members known to have left, for `orphaned`: those whose record was cleared, and the
        owner of `status` when this process never saw its record (it joined after that process left) but that
        process was of this host and runs no more, as its own record would have told."""
        owner = status.owner
        if owner is None or owner.node in self._gone or owner.node in self._members or status.handover is None:
            return self._gone
        return self._gone if lives(owner) else self._gone | {owner.node}

    def _retireorphaned(self, config: RuntimeConfig) -> bool:
        """Retire a robot `_orphans` found, on its own session (node/unclaimed.py), as its dead owner would have:
        `offline` with `retired` (this process's node), TD cleared. Looked at once more first, as in
        `_retire_unclaimed`."""
        from td2adaptor.runtime.bus.bus import BusError
        from td2adaptor.runtime.bus.security import SecurityError
        from td2adaptor.runtime.node.status import owner_fields
        from td2adaptor.runtime.node.unclaimed import retire

        robot = config.robot
        with self._lock:
            live = self._live()
            listed = set().union(*self._lists(live, self._mine()).values())
            status = self._statuses.get(robot)
            if robot in listed or status is None or not orphaned(status, self._left(status), live):
                self._orphaned.pop(robot, None)
                return False
            dead = status.owner.describe() if status.owner is not None else "a member"
        retired = {"node": self.me.node, "time": _now()}
        offline = status_event(config, self.fleet.model, "offline", **owner_fields(), retired=retired)
        try:
            done = retire(config, self.fleet.model, offline)
        except (BusError, SecurityError) as exc:
            done = False
            log.warning("robot %s: could not retire it with the fleet's settings: %s", robot, exc)
        with self._lock:
            if robot in self._orphaned:
                self._orphaned[robot] = None  # tried: once
        if done:
            log.info(
                "robot %s: retired: %s handed it over to member %s and left before it retired it, and no member "
                "lists it",
                robot,
                dead,
                status.handover,
            )
        return done

    def _free(self, robot: str, status: Status | None, live: set[str], gone: set[str]) -> bool:
        """May this process claim `robot`, whose retained status is `status`? Not while another live member
        starts it (its record's `starting`): that member serves it at the end of its start, and hands it over then
        if the plan changed meanwhile (`_admit`), rather than two processes starting it and one throwing its start
        away."""
        if self._started_by(robot, live) is not None:
            return False
        return self._free_status(robot, status, live, gone)

    def _started_by(self, robot: str, live: set[str]) -> str | None:
        """The live member other than this one whose record says it is starting `robot`, if one is."""
        with self._lock:
            for node in sorted(live - {self.me.node}):
                if robot in names(self._members.get(node, {}).get("starting")):
                    return node
        return None

    def _free_status(self, robot: str, status: Status | None, live: set[str], gone: set[str]) -> bool:
        if status is not None and status.retired and status.owner is not None and status.owner.node in live:
            with self._lock:  # its live owner no longer lists it: the others may drop it too in a moment
                since = self._retired_at.get(robot, 0.0)
            if time.monotonic() - since < RETIRED_WAIT:
                return False
        if status is None or status.state != "online" or status.owner is None:
            return True
        owner = status.owner
        if owner.node == self.me.node or status.handover == self.me.node:
            return True
        if status.handover is not None:  # its owner let it go, to another member
            if status.handover not in live:
                return True  # which is gone since
            since = self._waiting.setdefault(robot, time.monotonic())
            return time.monotonic() - since > HANDOVER_WAIT  # which does not take it: it is no longer its
        if owner.node in live:
            return False  # its owner serves it still: it hands it over first
        if owner.node in gone or not lives(owner):
            return True  # the owner died (or a stale record of this host)
        with self._lock:
            member = owner.node in self._members
            said = robot in self._foreign
            self._foreign.add(robot)
        if not member and not said:  # a process outside the share serves it: this one would wait in silence
            log.warning(
                "robot %s: not served by fleet %s: %s serves it and is no member of the fleet (started without "
                "--share?); the fleet takes it once that process stops",
                robot,
                self.name,
                owner.describe(),
            )
        return False

    def _admit(self, config: RuntimeConfig) -> str | None:
        """(Fleet.admit) The last look before this process takes the robot's session, after its ROS side came up
        (which may take seconds): a member that listed the robot meanwhile (its ROS graph showed it later than
        this one's) may be its owner now, and may have claimed it already, its status free when it looked. Two
        claims would have the broker take the session from one of them, which then goes off and on again:
        declined here instead, the robot is that member's (or handed over to it by this process later)."""
        robot = config.robot
        with self._lock:
            live = self._live()
            plan, mine = self._plan(live)
            status = self._statuses.get(robot)
        owner = plan.get(robot)
        if owner is not None and owner != self.me.node:
            # a member that listed it during this start (its graph showed it later): the robot is that member's
            # now; it waits while this process starts it (`_free`), so this start is not thrown away but served
            # and handed over at the next round, unless that member claimed it all the same (it did not see this
            # record in time)
            took = status is not None and status.owner is not None and status.owner.node == owner
            if robot not in mine or took or self._started_by(robot, {owner}) is not None:
                return f"member {owner} of the fleet serves it now"
            log.info(
                "robot %s: served here until member %s of the fleet takes it (listed by it meanwhile)", robot, owner
            )
        holder = status.owner if status is not None else None
        if status is not None and status.state == "online" and status.handover is None and holder is not None:
            if holder.node != self.me.node and holder.node in live:
                return f"{holder.describe()} serves it now"
        return None

    def _prepare(self, engine: Engine) -> None:
        """(Fleet.prepare) Before the robot is served: what its earlier owners admitted, then record what this
        process admits (admitted.py)."""
        config = engine.config
        words = self._taken_words(config.robot)
        if words is not None:
            engine.restarted = words
        window = config.freshness_window + config.clock_skew
        recorder = Recorder(self.bus, self.root, self.name, config.robot, self.me.node, window, self.book)
        learnt = seed(engine, self.book.of(config.robot), recorder)
        if learnt:
            log.info("robot %s: %d invokes its earlier owners admitted are known", config.robot, learnt)
        engine.guard = RecordingGuard(engine.guard, recorder)  # type: ignore[assignment]
        engine.ledger = RecordingLedger(engine.ledger, recorder)  # type: ignore[assignment]
        engine.outbox.ledger = engine.ledger
        raw = getattr(engine.bus, "bus", engine.bus)  # the robot's MQTT connection under its ThingBus

        def taken() -> bool:  # its session maybe another member's: lost (taken over, or the broker dropped it)
            return engine.failure is not None or not getattr(raw, "connected", True)

        # the robot's connection stopped serving (its session taken over): what its engine ends from now on (the
        # stop's "retired" end of a goal in flight) is the next owner's to record, not written over its entries
        engine.on_halt.append(lambda _reason: recorder.withdraw())
        trip = partial(round_trip, raw)
        port = AckedPort(engine.port, recorder.acknowledged, config.robot, taken, recorder.withdraw, trip)
        engine.port = port
        engine.kept = recorder.when_acknowledged  # a command is acknowledged once its entry is the broker's

        def gate(go: Callable[[bool], None]) -> None:  # a ROS action goal: sent as AckedPort starts a procedure
            # once the broker has its entry (member connection) and answered a request on the robot's own
            # connection, sent now: a session taken over meanwhile never answers there, and the end of that
            # connection's socket is read first (the member's acknowledgement says nothing of it)
            left, served = [2], [True]
            lock = threading.Lock()

            def settled(answered: bool = True) -> None:
                with lock:
                    left[0] -= 1
                    served[0] = served[0] and answered
                    if left[0]:
                        return
                go(port.serves(served[0], "the goal was sent"))

            trip(settled)
            recorder.when_acknowledged(settled)

        engine.gate = gate

    def _taken_words(self, robot: str) -> str | None:
        """What happened to the missions the robot's last owner left, when that was another member of the fleet: the
        start of the terminal words of each one this process cannot follow on (engine.py `restarted`; the robot's
        edge node did not restart, another process took the robot over)."""
        with self._lock:
            status = self._statuses.get(robot)
            owner = status.owner if status is not None else None
            if status is None or owner is None or owner.node == self.me.node:
                return None
            if owner.node not in self._members and owner.node not in self._gone:
                return None  # a process outside the fleet (a plain run) stopped: this one started it again
        if status.handover == self.me.node:
            return f"{owner.describe()} handed the robot over to {self.me.describe()} of fleet {self.name}"
        return (
            f"another process of fleet {self.name}, {self.me.describe()}, took the robot over after its edge node, "
            f"{owner.describe()}, was lost"
        )

    def _forget(self) -> None:
        """An entry this process published (an admin request it carried out) was cleared by another member: this
        process's connection must not publish it again when it reconnects (mqttbus.py keeps the last retained
        message of each topic), so it publishes the clearing too."""
        with self._lock:
            cleared, self._cleared = self._cleared, set()
        for topic in cleared:
            if topic in self._entries_mine:
                self._entries_mine.discard(topic)
                self.bus.publish(topic, b"", retain=True)

    def publish_entry(self, robot: str, entry: Mapping[str, Any] | None) -> None:
        """(admin.py) Add `robot` to the shared fleet (its retained entry), or remove it (None: cleared)."""
        topic = entries_topic(self.root, self.name, robot)
        if entry is None:
            self._entries_mine.discard(topic)
            self.bus.publish(topic, b"", retain=True)
        else:
            self._entries_mine.add(topic)
            self.bus.publish(topic, orjson.dumps(entry), retain=True)
        self.bus.flush(5)

    def _sweep(self) -> None:
        """Clear the entries of the robots served here that no copy of their invoke could still be fresh for."""
        now = time.time()
        if now - self._swept < SWEEP_PERIOD:
            return
        self._swept = now
        for robot, key in self.book.expired(set(self.fleet.robots(ORIGIN)), now):
            self.bus.publish(admitted_topic(self.root, self.name, robot, key), b"", retain=True)

    def _watch(self, engine: Any) -> None:
        """(Fleet.on_added) Hear when another member takes the robot's session: the robot is let go."""
        robot = engine.config.robot

        def halted(reason: str) -> None:
            if TAKEN_OVER in reason:
                log.warning("robot %s: %s", robot, reason)
                with self._lock:
                    self._taken.add(robot)
                self._wake.set()

        engine.on_halt.append(halted)

    def _release(self, robot: str, winner: str | None) -> None:
        """Hand `robot` over to `winner`: its missions in flight are left to it (the ledger, or the admitted
        entries on another host: admitted.py), the TD stays, the status stays online. Without a winner (no member
        lists it, or this one no longer does) retire it: missions ended, TD cleared, `offline` saying `retired`."""
        from td2adaptor.runtime.node.status import keeper_of, owner_fields

        with self._lock:
            record = self._members.get(winner or "")
        who = _describe(record, winner)
        engine = next((e for e in self.fleet.engines() if e.config.robot == robot), None)
        if engine is not None and winner is None:
            retired = {"node": self.me.node, "time": _now()}
            engine.offline = status_event(engine.config, engine.model, "offline", **owner_fields(), retired=retired)
        if engine is not None and winner is not None:
            with self._lock:  # until it is taken (`_unclaimed`)
                self._handed[robot] = (engine.config, time.monotonic())
            engine.td = None  # stays retained: the next owner publishes the same TD
            # the robot's side and its missions in flight as the last status said (they go on: the next owner
            # follows them), where it said `missions: 0` and no `robot` until the next owner's first status
            keeper = keeper_of(engine)
            now = {**(keeper.published() if keeper is not None else {}), **owner_fields()}
            engine.offline = status_event(
                engine.config,
                engine.model,
                "online",
                **{**now, "missions": len(engine.missions.running())},
                handover={"node": winner, "to": who, "time": _now()},
            )
        if winner is None:
            self.fleet.remove(robot, "is no longer in the fleet")
        else:
            self.fleet.remove(robot, f"was handed over to {who}", retire=False)

    def _took(self, robot: str, status: Status | None) -> None:
        """Note a robot this process took from another member (the member record and `fleet status` show it). A
        robot whose last owner was never a member (a plain `run` that stopped, long ago maybe) is started, not
        taken over."""
        if status is None or status.owner is None or status.owner.node == self.me.node:
            return
        with self._lock:
            member = status.owner.node in self._members or status.owner.node in self._gone
        if not member:
            log.info("robot %s: served by this member now (last served by %s)", robot, status.owner.describe())
            return
        how = "handover" if status.handover == self.me.node else "takeover"  # else its owner stopped or died
        entry = {"robot": robot, "from": status.owner.to_json(), "how": how, "time": _now()}
        self.takeovers.append(entry)
        log.info("robot %s: taken over from %s (%s)", robot, status.owner.describe(), how)

    def _can(self) -> list[str]:
        """What this process lists (its file's robots, the ones it sees): the plans are computed from these. The
        admin's robots are not in it: every member reads them from their entries."""
        with self._lock:
            return sorted({**self._found, **self._candidates})

    def _publish_record(self) -> None:
        with self._recording:  # several threads publish it (the share's, a start's, discovery's)
            self._publish()

    def _publish(self) -> None:
        record = {
            "owner": self.me.to_json(),
            "fleet": self.name,
            "joined": self._joined,
            "robots": sorted(self.fleet.robots(ORIGIN)),
            "can": self._can(),
            "found": sorted(self.robots("discovery")),  # what its discovery sees (`_heard`)
            "graph": self._graph,  # which ROS graph that is
            "unseen": sorted(self.unseen()),  # what the others' discovery found and this one does not see
            "starting": sorted(self.starting()),  # what it claimed and is starting now (`_free`)
            "admin": sorted(self.admin_robots()),  # what it learnt of the admin's entries (fleet status, tests)
            "takeovers": list(self.takeovers),
        }
        payload = orjson.dumps(record)
        if payload == self._last_record:
            return
        self._last_record = payload
        message = Message(members_topic(self.root, self.name, self.me.node), payload, retain=True)
        self.bus.birth = message  # type: ignore[attr-defined]  # published again on every reconnection
        self.bus.publish(message.topic, message.payload, retain=True)


def _still_handing(status: Status | None, node: str) -> bool:
    """Whether the robot's status (None: none read yet) may still be member `node`'s hand-over: not taken by
    another member, not `offline`."""
    return status is None or (status.state == "online" and status.owner is not None and status.owner.node == node)


def _describe(record: Mapping[str, Any] | None, node: str | None) -> str:
    owner = Owner.from_json(record.get("owner")) if record is not None else None
    if owner is not None:
        return owner.describe()
    return f"member {node}" if node else "no member"


def share_bus(template: RuntimeConfig, model: Any, *, name: str, keepalive: int, node: str | None = None) -> Any:
    """The member connection: a clean session of its own, a short keepalive, a will that clears the record."""
    from td2adaptor.runtime.bus.mqttbus import MqttBus
    from td2adaptor.runtime.node.app import bus_security

    address, security = bus_security(template, model)
    node = node or this_process().node
    return MqttBus.sessionless(
        address,
        security,
        f"member-{name}-{node}",
        will=Message(members_topic(template.topic_root, name, node), b"", retain=True),
        mqtt_version=template.mqtt_version,
        keepalive=keepalive,
    )


def _no_check(_configs: Sequence[RuntimeConfig]) -> None:
    """A shared fleet claims a robot only once its status says it is free (`Share._free`)."""
