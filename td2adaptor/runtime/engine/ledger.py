"""The missions a node follows, kept durably: so a restart can finish each one and answer a resent invoke.

A node killed mid-mission (SIGKILL, a power cut of its host) forgets the missions it followed: the robot
finishes them, but nobody reports it, and a resent invoke id is a redelivery the replay guard ignores. The
ledger keeps, in the robot's SQLite file beside the replay guard's ids (`RuntimeConfig.ids_file`), one row
per invoke the node took: the component and action, the invoke's id and correlation, the mission id and the
goal id the robot gave, the state, the feedback numbering, and the last feedback event published (its text).

It is written at the moments that matter, each write committed before the event it records is published
(WAL, synchronous=NORMAL: a write survives the process being killed; only the host losing power can undo
the last ones): when the invoke is taken (`open`), with every feedback event that changes the state (so
with the robot's mission id once it accepted), at the end (`phase` "ending", with the terminal event), and
once that is published (`phase` "done"). A ROS action goal's feedback messages do not change the state:
not each is written; instead the numbering is reserved `SEQ_BLOCK` ahead, so a restart never reuses a
number already published (the next one may skip some: a gap, never a repeat).

At the next start, `pending()` gives every mission not done: the engine follows a procedure again (its
mission id is known) and a ROS action goal (by the goal id the server gave it), or ends it `failed` ("the edge
node restarted ..."), and publishes again a terminal event it had stored but maybe not sent. Done rows are
dropped after `keep` seconds (the replay window: a resent invoke older than that is refused as expired anyway).
Until then a ROS action goal's row also answers a query or cancel of the goal by its id once this run no longer
follows it (`ended_goal`: a goal that ended in the last run, or before the action's next goal). That look is a
scan of the robot's rows (a few hundred: the replay window's), about 0.1-0.3 ms, on that rare path only: an index
on the goal id would cost every invoke's writes instead.
"""

from __future__ import annotations

import logging
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from td2adaptor.runtime.engine.replay import Store
from td2adaptor.runtime.events import new_id

log = logging.getLogger("td2adaptor.runtime")

#: feedback numbers reserved ahead for feedback that is not written one by one (ROS action feedback)
SEQ_BLOCK = 100

_SCHEMA = """
CREATE TABLE IF NOT EXISTS missions (
    key TEXT PRIMARY KEY,
    event_id TEXT,
    topic TEXT NOT NULL,
    kind TEXT NOT NULL,
    component TEXT NOT NULL,
    action TEXT NOT NULL,
    correlation TEXT,
    started REAL NOT NULL,
    mission INTEGER,
    goal TEXT,
    state TEXT,
    seq INTEGER NOT NULL DEFAULT 0,
    reserved INTEGER NOT NULL DEFAULT 0,
    latest TEXT,
    phase TEXT NOT NULL DEFAULT 'running',
    until REAL
);
CREATE INDEX IF NOT EXISTS missions_by_event ON missions (event_id);
CREATE INDEX IF NOT EXISTS missions_by_phase ON missions (phase);
"""


@dataclass(frozen=True)
class Record:
    """One mission as the ledger has it (see the module docstring)."""

    key: str
    event_id: str | None
    topic: str
    kind: str  # "procedure", "goal" or "call"
    component: str
    action: str
    correlation: str | None
    started: float  # wall clock, seconds since the epoch
    mission: int | None
    goal: str | None
    state: str | None
    seq: int  # the last feedback number published
    reserved: int  # no published number is above this
    latest: str | None  # the last feedback event published, as its text
    phase: str  # "running", "ending" (terminal stored, maybe not sent) or "done"


class Ledger:
    """The durable record of missions (see the module docstring). Every method may be called from any thread;
    a failing write is logged, never raised: the ledger must not cost a mission."""

    def __init__(self, path: Path | Store | None, *, keep: float, clock: Callable[[], float] = time.time) -> None:
        self.keep = keep
        self.clock = clock
        self._store = path if isinstance(path, Store) else Store(path)
        self.durable = self._store.durable
        db, self._lock = self._store.use()
        self._db: sqlite3.Connection | None = db
        with self._lock:
            db.executescript(_SCHEMA)
        self._next_prune = 0.0

    def _write(self, sql: str, args: tuple[object, ...]) -> None:
        with self._lock:
            if self._db is None:
                return
            try:
                self._db.execute(sql, args)
            except sqlite3.Error as exc:
                log.error("the mission ledger could not be written (%s): a restart may not finish this mission", exc)

    def open(
        self,
        *,
        event_id: str | None,
        topic: str,
        kind: str,
        component: str,
        action: str,
        correlation: str | None,
    ) -> str:
        """Record an invoke the node took; its key."""
        key = new_id()  # unique as a UUID's 32 hex digits, without a system call (os.urandom) per invoke
        now = self.clock()
        if now >= self._next_prune:
            self._next_prune = now + 60.0
            self._write("DELETE FROM missions WHERE phase = 'done' AND until < ?", (now,))
        self._write(
            "INSERT INTO missions (key, event_id, topic, kind, component, action, correlation, started) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (key, event_id, topic, kind, component, action, correlation, now),
        )
        return key

    def event(
        self,
        key: str,
        *,
        mission: int | None,
        goal: str | None,
        state: str,
        seq: int,
        reserved: int,
        latest: str,
        terminal: bool,
    ) -> None:
        """Record a feedback event about to be published (a terminal one: phase "ending")."""
        self._write(
            "UPDATE missions SET mission = ?, goal = ?, state = ?, seq = ?, reserved = ?, latest = ?, phase = ? "
            "WHERE key = ?",
            (mission, goal, state, seq, reserved, latest, "ending" if terminal else "running", key),
        )

    def reserve(self, key: str, reserved: int) -> None:
        """Record that feedback numbers up to `reserved` may be published without a write each."""
        self._write("UPDATE missions SET reserved = ? WHERE key = ?", (reserved, key))

    def done(self, key: str) -> None:
        """The terminal event is published: nothing is left to do for this mission after a restart."""
        self._write("UPDATE missions SET phase = 'done', until = ? WHERE key = ?", (self.clock() + self.keep, key))

    def pending(self) -> list[Record]:
        """Every mission not done, oldest first (at start: what the last run left)."""
        return self._records("SELECT * FROM missions WHERE phase != 'done' ORDER BY started", ())

    def latest(self, event_id: str, topic: str) -> Record | None:
        """The mission an invoke with this id (on this topic) started, if the ledger has it."""
        found = self._records("SELECT * FROM missions WHERE event_id = ? AND topic = ?", (event_id, topic))
        return found[0] if found else None

    def ended_goal(self, component: str, action: str, goal: str | None) -> Record | None:
        """The row of the ROS action goal `goal` of `component`'s `action` (None: its latest goal) once its
        terminal event is stored, if the ledger still keeps it (done rows: `keep` seconds)."""
        sql = (
            "SELECT * FROM missions WHERE kind = 'goal' AND component = ? AND action = ? AND goal IS NOT NULL "
            "AND state IN ('finished', 'cancelled', 'failed') AND latest IS NOT NULL "
            "AND (phase = 'ending' OR (phase = 'done' AND until >= ?))"
        )
        args: tuple[object, ...] = (component, action, self.clock())
        if goal is not None:
            sql, args = sql + " AND goal = ?", (*args, goal)
        found = self._records(sql + " ORDER BY started DESC LIMIT 1", args)
        return found[0] if found else None

    def _records(self, sql: str, args: tuple[object, ...]) -> list[Record]:
        with self._lock:
            if self._db is None:
                return []
            try:
                cursor = self._db.execute(sql, args)
                names = [c[0] for c in cursor.description]
                rows = [dict(zip(names, row, strict=True)) for row in cursor.fetchall()]
            except sqlite3.Error as exc:
                log.error("the mission ledger could not be read (%s)", exc)
                return []
        return [
            Record(
                key=str(r["key"]),
                event_id=r["event_id"],
                topic=str(r["topic"]),
                kind=str(r["kind"]),
                component=str(r["component"]),
                action=str(r["action"]),
                correlation=r["correlation"],
                started=float(r["started"]),
                mission=r["mission"],
                goal=r["goal"],
                state=r["state"],
                seq=int(r["seq"]),
                reserved=int(r["reserved"]),
                latest=r["latest"],
                phase=str(r["phase"]),
            )
            for r in rows
        ]

    def close(self) -> None:
        with self._lock:
            if self._db is None:
                return
            self._db = None
        self._store.release()
