"""The invokes a robot's owner admitted, carried on the broker, so that a process on another host that takes the
robot over (node/share.py) runs none of them again and ends the missions in flight.

On one host the robot's replay guard and mission ledger (engine/replay.py, ledger.py, in `state_dir`) carry that
from one owner to the next. Hosts do not share a state directory, so in a shared fleet each owner also publishes,
for every invoke it admits, one retained **entry** on `<root>/.fleet/<fleet>/admitted/<robot>/<key>` (key: a
hash of the invoke's id and topic): the id, topic, content digest and time the guard checked, and the ledger's
record of its mission (state, mission id, the last feedback event published, phase), published again whenever
the ledger writes it. The mission's start waits until the broker has acknowledged the entry (`AckedPort`), so an
owner that dies can only have run an invoke whose entry the broker has.

The next owner reads the entries (the share follows them all, `Book`) and `seed`s its engine with them before it
serves: the guard learns the ids (a redelivered or resent invoke is answered, not run), the ledger the missions
(followed again or ended `failed`, each with one terminal event, by the engine's recovery). Entries are cleared
once no copy of their invoke could still be fresh (`sweep`: time + freshness window + clock skew).
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

import orjson

from td2adaptor.runtime.bus.bus import Bus, Message, when_flushed
from td2adaptor.runtime.engine.replay import Verdict, parse_time
from td2adaptor.runtime.ros.port import PortUnavailable

log = logging.getLogger("td2adaptor.runtime.share")

#: how long a mission's start waits for the broker to acknowledge its entry before it starts anyway (logged)
ACK_TIMEOUT = 5.0


def admitted_topic(root: str, fleet: str, robot: str = "+", key: str = "+") -> str:
    return f"{root}/.fleet/{fleet}/admitted/{robot}/{key}"


def entry_key(event_id: str, topic: str) -> str:
    return hashlib.sha256(f"{event_id}\x00{topic}".encode()).hexdigest()[:24]


class Book:
    """Every robot's entries as the broker has them (the share's connection follows them all)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._entries: dict[str, dict[str, dict[str, Any]]] = {}  # robot -> key -> entry
        self._before: dict[str, dict[str, dict[str, Any]]] = {}  # robot -> key -> the entry of its owner before
        # (robot, key) -> (owner, its entry's time, what to call with the entry before it once the broker echoed it)
        self._awaited: dict[tuple[str, str], tuple[str, Any, Callable[[dict[str, Any]], None]]] = {}

    def take(self, message: Message) -> None:
        parts = message.topic.split("/")
        robot, key = parts[-2], parts[-1]
        call: tuple[Callable[[dict[str, Any]], None], dict[str, Any]] | None = None
        with self._lock:
            if not message.payload:
                self._entries.get(robot, {}).pop(key, None)
                self._before.get(robot, {}).pop(key, None)
                self._awaited.pop((robot, key), None)
                return
            try:
                entry = orjson.loads(message.payload)
            except orjson.JSONDecodeError:
                return
            if not isinstance(entry, dict):
                return
            old = self._entries.setdefault(robot, {}).get(key)
            if old is not None and old.get("owner") != entry.get("owner"):
                self._before.setdefault(robot, {})[key] = old
            self._entries[robot][key] = entry
            awaited = self._awaited.get((robot, key))
            if awaited is not None and awaited[:2] == (entry.get("owner"), entry.get("at")):
                del self._awaited[(robot, key)]
                before = self._before.get(robot, {}).get(key)
                if before is not None and before.get("owner") != entry.get("owner"):
                    call = (awaited[2], before)
        if call is not None:
            call[0](call[1])

    def theirs(self, robot: str, key: str, me: str) -> dict[str, Any] | None:
        """The last entry of `key` that an owner other than `me` published, as far as the broker has told."""
        with self._lock:
            for entry in (self._entries.get(robot, {}).get(key), self._before.get(robot, {}).get(key)):
                if entry is not None and entry.get("owner") != me:
                    return entry
        return None

    def theirs_now_and_after(
        self, robot: str, key: str, mine: Mapping[str, Any], then: Callable[[dict[str, Any]], None]
    ) -> dict[str, Any] | None:
        """The last entry of `key` another owner than `mine`'s published as far as the broker has told (`theirs`),
        and `then(entry)` with the one before `mine` once the broker echoes it (unless it did already): the broker
        sends everything it had before it first, also when this process's connection was lost meanwhile (a hung
        process's, dropped by its keepalive) and the others' entry came back retained on the new one."""
        me = str(mine.get("owner"))
        with self._lock:
            latest = self._entries.get(robot, {}).get(key)
            if latest is None or (latest.get("owner"), latest.get("at")) != (me, mine.get("at")):
                self._awaited[(robot, key)] = (me, mine.get("at"), then)
        return self.theirs(robot, key, me)

    def of(self, robot: str) -> list[dict[str, Any]]:
        with self._lock:
            return sorted(self._entries.get(robot, {}).values(), key=lambda e: float(e.get("at") or 0))

    def expired(self, robots: set[str], now: float) -> list[tuple[str, str]]:
        """(robot, key) of the entries of `robots` that no copy of their invoke could still be fresh for."""
        with self._lock:
            return [
                (robot, key)
                for robot in robots
                for key, entry in self._entries.get(robot, {}).items()
                if float(entry.get("until") or 0) < now
            ]


def seed(engine: Any, entries: list[dict[str, Any]], recorder: Recorder) -> int:
    """Teach `engine` (before it starts, and before `recorder` wraps its guard and ledger) the invokes the robot's
    earlier owners admitted: the guard its ids, the ledger its missions (those it has already, from a shared state
    directory, are left); `recorder` keeps their entries up to date from now on. How many it learnt."""
    learnt = 0
    for e in entries:
        event_id, topic = e.get("id"), e.get("topic")
        if not isinstance(event_id, str) or not isinstance(topic, str):
            continue
        if engine.ledger.latest(event_id, topic) is not None:
            continue  # this host's ledger has it (the same state directory)
        sent, digest = e.get("sent"), e.get("digest")
        verdict = engine.guard.check(event_id, topic, sent if isinstance(sent, str) else None, digest)
        if verdict is not Verdict.NEW:
            continue  # expired, or known already
        key = engine.ledger.open(
            event_id=event_id,
            topic=topic,
            kind=str(e.get("kind") or "call"),
            component=str(e.get("component") or ""),
            action=str(e.get("action") or ""),
            correlation=e.get("correlation"),
        )
        latest = e.get("latest")
        if isinstance(latest, str):
            engine.ledger.event(
                key,
                mission=e.get("mission"),
                goal=e.get("goal"),
                state=str(e.get("state") or ""),
                seq=int(e.get("seq") or 0),
                reserved=int(e.get("reserved") or 0),
                latest=latest,
                terminal=e.get("phase") in ("ending", "done"),
            )
        if e.get("phase") == "done":
            engine.ledger.done(key)
        else:
            recorder.adopt(key, e)  # its end, when the engine's recovery gives it one, is recorded too
        learnt += 1
    return learnt


#: ids a robot's recorder keeps the time and digest of, waiting for their invoke's entry (`Recorder.checked`)
CHECKED_KEPT = 256


class Recorder:
    """One robot's entries, published as its engine's guard and ledger write (see the module docstring)."""

    def __init__(
        self, bus: Bus, root: str, fleet: str, robot: str, owner: str, window: float, book: Book | None = None
    ) -> None:
        self.bus = bus
        self.book = book
        self.lost = False  # the robot's session is another process's now: nothing more is recorded (`withdraw`)
        self.root, self.fleet, self.robot, self.owner = root, fleet, robot, owner
        self.window = window  # freshness window + clock skew: how long an entry is kept after its invoke's time
        self._lock = threading.Lock()
        self._checked: dict[tuple[str, str], tuple[str | None, str | None]] = {}  # (id, topic) -> (sent, digest)
        self._entries: dict[str, dict[str, Any]] = {}  # ledger key -> entry
        self._opened: set[str] = set()  # ledger keys of the invokes admitted here (not learnt from an earlier owner)

    def checked(self, event_id: str, topic: str, sent: str | None, digest: str | None) -> None:
        """(the guard, for every new id) Its time and digest, for the entry `opened` publishes right after, on the
        same turn of the engine's loop, when it is an invoke. Queries, cancels and writes are never opened: only
        the last `CHECKED_KEPT` are kept (they were kept for ever, one per command a shared robot ever took)."""
        with self._lock:
            self._checked[(event_id, topic)] = (sent, digest)
            while len(self._checked) > CHECKED_KEPT:
                del self._checked[next(iter(self._checked))]

    def opened(self, key: str, fields: Mapping[str, Any]) -> None:
        event_id, topic = fields.get("event_id"), str(fields.get("topic"))
        if not isinstance(event_id, str):
            return  # no id: nothing a later owner could recognise
        with self._lock:
            sent, digest = self._checked.pop((event_id, topic), (None, None))
        stamp = parse_time(sent) if sent else None
        entry = {
            "id": event_id,
            "topic": topic,
            "sent": sent,
            "digest": digest,
            "kind": fields.get("kind"),
            "component": fields.get("component"),
            "action": fields.get("action"),
            "correlation": fields.get("correlation"),
            "phase": "running",
            "owner": self.owner,
            "at": time.time(),
            "until": (stamp if stamp is not None else time.time()) + self.window,
        }
        with self._lock:
            self._entries[key] = entry
            self._opened.add(key)
        self._publish(entry)

    def adopt(self, key: str, entry: Mapping[str, Any]) -> None:
        with self._lock:
            self._entries[key] = {**entry, "owner": self.owner}

    def changed(self, key: str, **fields: Any) -> None:
        with self._lock:
            entry = self._entries.get(key)
            if entry is None:
                return
            entry.update(fields)
            entry = dict(entry)
            if entry.get("phase") == "done":
                self._entries.pop(key, None)
                self._opened.discard(key)
        self._publish(entry)

    def withdraw(self) -> None:
        """The robot's session was lost before a mission started (`AckedPort`), or its connection stopped serving
        (share.py: taken over): its next owner may have run the invoke already, or ended it, whose entry this
        process's own overwrote. Put back the entry of each invoke admitted here that another owner admitted too,
        as it published it last, and record nothing more (not the end this process's stop gives a mission)."""
        with self._lock:
            self.lost = True
            mine = [dict(e) for k, e in self._entries.items() if k in self._opened]
        for entry in mine:
            if self.book is None:
                continue
            key = entry_key(str(entry["id"]), str(entry["topic"]))
            topic = admitted_topic(self.root, self.fleet, self.robot, key)
            # this process's own entry may reach the broker later than the others' (its connection lost, its
            # entry sent on the next one): put back then what the broker had before it
            theirs = self.book.theirs_now_and_after(self.robot, key, entry, partial(self._send, topic))
            if theirs is not None:
                self._send(topic, theirs)

    def _publish(self, entry: Mapping[str, Any]) -> None:
        if self.lost:
            return
        self._send(
            admitted_topic(self.root, self.fleet, self.robot, entry_key(str(entry["id"]), str(entry["topic"]))), entry
        )

    def _send(self, topic: str, entry: Mapping[str, Any]) -> None:
        try:
            self.bus.publish(topic, orjson.dumps(entry), retain=True)
        except Exception as exc:  # noqa: BLE001 - the robot is served all the same; a takeover may then run it again
            log.warning(
                "robot %s: the admitted invoke %s could not be recorded on the broker: %s", self.robot, entry["id"], exc
            )

    def acknowledged(self) -> bool:
        """Wait until the broker has every entry published so far (a mission's start, on the call pool)."""
        return self.bus.flush(ACK_TIMEOUT)

    def when_acknowledged(self, then: Callable[[], None]) -> None:
        """`then()` once the broker has every entry published so far, without waiting for it (the engine's
        loop: a command's acknowledgement, a goal's start)."""
        when_flushed(self.bus, then)


class RecordingGuard:
    """The engine's replay guard, telling `recorder` the time and digest of each new id."""

    def __init__(self, guard: Any, recorder: Recorder) -> None:
        self._guard = guard
        self._recorder = recorder

    def check(self, event_id: str | None, topic: str, sent: str | None, digest: str | None = None) -> Verdict:
        verdict: Verdict = self._guard.check(event_id, topic, sent, digest)
        if verdict is Verdict.NEW and event_id is not None:
            self._recorder.checked(event_id, topic, sent, digest)
        return verdict

    def adopt(self, event_id: str, topic: str, sent: str | None, digest: str | None = None) -> None:
        self._guard.adopt(event_id, topic, sent, digest)
        self._recorder.checked(event_id, topic, sent, digest)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._guard, name)


class RecordingLedger:
    """The engine's mission ledger, publishing each invoke's entry as it writes the invoke's record."""

    def __init__(self, ledger: Any, recorder: Recorder) -> None:
        self._ledger = ledger
        self._recorder = recorder

    def open(self, **fields: Any) -> str:
        key: str = self._ledger.open(**fields)
        self._recorder.opened(key, fields)
        return key

    def event(self, key: str, **fields: Any) -> None:
        self._ledger.event(key, **fields)
        terminal = fields.pop("terminal", False)
        self._recorder.changed(key, **fields, phase="ending" if terminal else "running")

    def reserve(self, key: str, reserved: int) -> None:
        self._ledger.reserve(key, reserved)
        self._recorder.changed(key, reserved=reserved)

    def done(self, key: str) -> None:
        self._ledger.done(key)
        self._recorder.changed(key, phase="done")

    def __getattr__(self, name: str) -> Any:
        return getattr(self._ledger, name)


class AckedPort:
    """The robot's port, whose procedure missions and plain calls start only once the broker has their entries,
    and which runs nothing (nor writes a property) once the robot's session was taken over: a process that hung
    and resumes reads the commands the broker wrote into its socket meanwhile before the end of that socket
    (mosquitto just closes a connection whose session another client took), and the next owner got them too and
    ran them. The member connection's acknowledgement of the entry says nothing of the robot's connection (its
    closed socket may be read later): a round trip on the robot's own connection (`trip`: share.py, MqttBus
    `round_trip`) says whether that connection still served its session, and `taken` whether it is still there.
    The port's calls without a waiting thread (`QuickCall`) are declined, so that these go through here."""

    def __init__(
        self,
        port: Any,
        acknowledged: Callable[[], bool],
        robot: str,
        taken: Callable[[], bool] = lambda: False,
        withdraw: Callable[[], None] = lambda: None,
        trip: Callable[[Callable[[bool], None]], None] | None = None,
    ) -> None:
        self._port = port
        self._acknowledged = acknowledged
        self._robot = robot
        self._taken = taken
        self._withdraw = withdraw
        self._trip = trip

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Any:
        self._may_run("the invoke started", entry=True)
        return self._port.start(component, action, payload, timeout)

    def call(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Any:
        self._may_run("the invoke started", entry=True)
        return self._port.call(component, action, payload, timeout)

    def write_property(self, component: str, name: str, value: Any) -> None:
        self._may_run("the property was written", entry=False)  # a write has no entry (invokes only)
        self._port.write_property(component, name, value)

    def try_start(self, *_args: Any) -> bool:
        return False  # on the call pool (`start`): the waits above hold a thread

    def try_call(self, *_args: Any) -> bool:
        return False  # as `try_start` (`call`)

    def _may_run(self, what: str, *, entry: bool) -> None:
        """(a pool thread) Wait for the broker's acknowledgement of the entry (`entry`) and the round trip on the
        robot's connection, sent at once so that both come together; raise when the session may be another's."""
        answered, served = threading.Event(), [True]
        if self._trip is not None:

            def told(fine: bool) -> None:
                served[0] = fine
                answered.set()

            self._trip(told)
        if entry and not self._acknowledged():
            log.warning(
                "robot %s: the broker did not acknowledge the admitted invoke in time; starting it", self._robot
            )
        if self._trip is not None and not answered.wait(ACK_TIMEOUT):
            log.warning("robot %s: the broker did not answer on the robot's connection in time", self._robot)
        if not self.serves(served[0], what):
            raise PortUnavailable(
                "the edge node lost its connection to the broker, and another one of the fleet may serve the robot "
                "now: not run here"
            )

    def serves(self, answered: bool, what: str) -> bool:
        """Whether the robot's connection still serves its session (`answered`: the round trip on it came back),
        so that `what` may be done here; if not, say so and withdraw this process's entries (a ROS goal's gate,
        share.py, decides the same way)."""
        if answered and not self._taken():
            return True
        log.warning("robot %s: its connection was lost before %s: not run here", self._robot, what)
        self._withdraw()
        return False

    def __getattr__(self, name: str) -> Any:
        return getattr(self._port, name)
