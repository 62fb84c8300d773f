"""Commands are fresh and unique: the freshness window on an event's `time`, and event ids remembered durably.

An MQTT broker delivers a QoS 1 message at least once, and a persistent session keeps what was published
while the node was away; a recorded command can also be published again by anyone allowed to publish. So:

* an event whose `time` is older than `freshness_window` by the node's clock, or more than `clock_skew` in
  the future, is answered with an error event and not run (`expired` / `from-the-future`): the skew lets a
  sender's clock run ahead of the node's; one that runs behind shortens the window for its events by as much;
* a `time` that names no instant (month 13, 30 February, hour 24, offset +99:99, second 60) is refused
  (`invalid-event`, naming what is wrong), never taken for an event without a time;
* an event id is remembered for as long as an event carrying it could still be fresh, in a small SQLite file
  per robot (so a restart forgets nothing that could still be replayed), with a digest of the event: the same
  id on the same topic with the same content is a redelivery and handled once (ignored in silence); the same
  id on another topic, or with other content, is another command under a used id and is answered with an
  error (`id-reused`);
* an id another run of the node remembered (a restart, or another process of a shared fleet on this host, whose
  state directory it shares) is `inherited`: a redelivery too, but that run may have stopped between
  remembering the id and taking the command (killed in that moment: the broker then gives the command again,
  since it was never acknowledged), so the engine asks its mission ledger whether the command was taken
  (engine.py): a command never taken runs now (`adopt`), one taken is answered again.

The store is bounded by the window, not by a count: ids older than the window are dropped as they age out.
Events without `time` are accepted and remembered for the window from their arrival.
"""

from __future__ import annotations

import calendar
import hashlib
import json
import os
import re
import sqlite3
import threading
import time
from collections.abc import Callable
from datetime import datetime, timezone
from enum import Enum
from pathlib import Path
from typing import Any

# RFC 3339's date-time, its fields apart (ASCII digits only: `\d` would take any script's)
_RFC3339 = re.compile(
    r"^([0-9]{4})-([0-9]{2})-([0-9]{2})T([0-9]{2}):([0-9]{2}):([0-9]{2})(\.[0-9]+)?(Z|([+-])([0-9]{2}):([0-9]{2}))$",
    re.IGNORECASE,
)
_MONTHS = "January February March April May June July August September October November December".split()


class Verdict(str, Enum):
    NEW = "new"
    DUPLICATE = "duplicate"  # the same id, topic and content: a redelivery, handled once
    INHERITED = "inherited"  # a DUPLICATE another run remembered: taken by it, or not yet (see the module doc)
    REUSED = "id-reused"  # the same id on another topic or with other content: answered with an error
    EXPIRED = "expired"
    FUTURE = "from-the-future"
    BAD_TIME = "invalid-event"  # a `time` that names no instant (see `time_problem`)


def digest(event: Any) -> str:
    """A digest of an event's content (a parsed JSON document): equal for the same event however serialised.
    Its `time` is left out: the same command sent again later is still the same command (and a WoT message,
    which the node stamps on arrival, would otherwise never be one)."""
    if isinstance(event, dict):
        event = {k: v for k, v in event.items() if k != "time"}
    text = json.dumps(event, sort_keys=True, separators=(",", ":"), ensure_ascii=False, default=str)
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


def parse_time(text: str) -> float | None:
    """Seconds since the epoch of an RFC 3339 time, or None when it is not one (`time_problem` says why)."""
    found = _instant(text)
    return found if isinstance(found, float) else None


def time_problem(text: str) -> str | None:
    """Why `text` is no RFC 3339 time naming a real instant, in words for the sender; None when it is one."""
    found = _instant(text)
    return found if isinstance(found, str) else None


def _instant(text: str) -> float | str:
    """The instant `text` names (seconds since the epoch), or what is wrong with it."""
    match = _RFC3339.match(text)
    if match is None:
        return "not an RFC 3339 date-time such as 2026-05-01T12:00:00Z"
    year, month, day, hour, minute, second = (int(match[i]) for i in range(1, 7))
    if year == 0:
        return "year 0000 is before year 1, the first this node handles"
    if not 1 <= month <= 12:
        return f"month {match[2]} does not exist (01 to 12)"
    if not 1 <= day <= calendar.monthrange(year, month)[1]:
        return f"{_MONTHS[month - 1]} {match[1]} has no day {match[3]}"
    if hour > 23:
        return f"hour {match[4]} does not exist (00 to 23)"
    if minute > 59:
        return f"minute {match[5]} does not exist (00 to 59)"
    if second == 60:
        return "second 60 (a leap second) is not accepted: give the instant after it, 00 of the next minute"
    if second > 59:
        return f"second {match[6]} does not exist (00 to 59)"
    if match[9] is not None and (int(match[10]) > 23 or int(match[11]) > 59):
        return f"offset {match[9]}{match[10]}:{match[11]} is no time zone offset (hours 00 to 23, minutes 00 to 59)"
    zone = "+00:00" if match[8].upper() == "Z" else match[8]
    fraction = (match[7] or "")[:7]  # to the microsecond: what a timestamp holds
    try:
        return datetime.fromisoformat(text[:19].upper() + fraction + zone).timestamp()
    except (ValueError, OverflowError):
        return "outside the times this node can handle"


def open_store(path: Path | None, *, timeout: float) -> sqlite3.Connection:
    """A connection to the robot's SQLite file (in memory without a path), which the replay guard and the mission
    ledger share (`Store`): any thread, autocommit; WAL with synchronous NORMAL, so a write costs no fsync of its
    own and a crash of the process loses nothing committed. `timeout`: how long a write waits for another
    connection's (another process of the machine, or a test's)."""
    target = ":memory:"
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        target = str(path)
    db = sqlite3.connect(target, check_same_thread=False, isolation_level=None, timeout=timeout)
    db.execute("PRAGMA journal_mode=WAL")
    db.execute("PRAGMA synchronous=NORMAL")
    return db


class Store:
    """The robot's SQLite file opened once: the connection and the lock its users (the replay guard and the mission
    ledger) take around each use. One connection instead of one each: a connection costs about 120 KiB (SQLite's
    lookaside and page cache, the WAL index's mapping), paid per robot in a fleet process, and the two no longer
    wait for each other's write lock. Closed when its last user closes."""

    def __init__(self, path: Path | None) -> None:
        self.durable = path is not None
        self.db = open_store(path, timeout=5.0)
        self.lock = threading.Lock()
        self._users = 0

    def use(self) -> tuple[sqlite3.Connection, threading.Lock]:
        """The connection and its lock, for one more user (who calls `release` once)."""
        with self.lock:
            self._users += 1
        return self.db, self.lock

    def release(self) -> None:
        with self.lock:
            self._users -= 1
            if self._users <= 0:
                self.db.close()


class ReplayGuard:
    """Decides whether an inbound event may run: fresh, and its id not seen (see the module docstring)."""

    def __init__(
        self,
        path: Path | Store | None,
        *,
        window: float,
        skew: float,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.window = window
        self.skew = skew
        self.clock = clock
        self._store = path if isinstance(path, Store) else Store(path)
        self.durable = self._store.durable
        self._db, self._lock = self._store.use()
        self._db.execute(
            "CREATE TABLE IF NOT EXISTS seen (id TEXT PRIMARY KEY, topic TEXT NOT NULL, until REAL, digest TEXT)"
        )
        columns = {row[1] for row in self._db.execute("PRAGMA table_info(seen)")}
        if "digest" not in columns:  # a store written before digests: its ids keep an unknown content (NULL)
            self._db.execute("ALTER TABLE seen ADD COLUMN digest TEXT")
        if "run" not in columns:  # a store written before runs: its ids are an earlier run's (NULL)
            self._db.execute("ALTER TABLE seen ADD COLUMN run TEXT")
        self.run = os.urandom(8).hex()  # this guard's run: the ids it remembers are its own
        self._next_prune = 0.0

    def check(self, event_id: str | None, topic: str, sent: str | None, digest: str | None = None) -> Verdict:
        """The verdict for an event (`digest`: of its content, see `digest()`); a NEW id is remembered, with the
        topic and digest, until it could no longer be fresh. Where either digest is unknown, the same id on the
        same topic counts as a redelivery."""
        now = self.clock()
        stamp = None
        if sent is not None:
            found = _instant(sent)
            if isinstance(found, str):
                return Verdict.BAD_TIME
            stamp = found
            if stamp < now - self.window:
                return Verdict.EXPIRED
            if stamp > now + self.skew:
                return Verdict.FUTURE
        if event_id is None:
            return Verdict.NEW
        until = (stamp if stamp is not None else now) + self.window + self.skew
        with self._lock:
            self._prune(now)
            # remembered in one statement, so that two runs sharing the store (a shared fleet's processes on one
            # host, both given the same command on the robot's session) that check one id at once agree: the
            # first to write it has it, the other gets its verdict
            added = self._db.execute(
                "INSERT OR IGNORE INTO seen (id, topic, until, digest, run) VALUES (?, ?, ?, ?, ?)",
                (event_id, topic, until, digest, self.run),
            )
            if added.rowcount == 1:
                return Verdict.NEW
            row = self._db.execute("SELECT topic, digest, run FROM seen WHERE id = ?", (event_id,)).fetchone()
        if row is None:  # another run pruned it in between: the engine asks its ledger whether it was taken
            return Verdict.INHERITED
        same = row[0] == topic and (row[1] is None or digest is None or row[1] == digest)
        if not same:
            return Verdict.REUSED
        return Verdict.DUPLICATE if row[2] == self.run else Verdict.INHERITED

    def adopt(self, event_id: str, topic: str, sent: str | None, digest: str | None = None) -> None:
        """Make an `inherited` id (`check`'s arguments) this run's: the command it names runs here (a second
        redelivery of it is a `duplicate` from now on)."""
        with self._lock:
            self._db.execute("UPDATE seen SET run = ? WHERE id = ?", (self.run, event_id))

    def _prune(self, now: float) -> None:
        if now >= self._next_prune:
            self._db.execute("DELETE FROM seen WHERE until < ?", (now,))
            self._next_prune = now + min(60.0, self.window / 10 or 1.0)

    def __len__(self) -> int:
        with self._lock:
            return int(self._db.execute("SELECT COUNT(*) FROM seen").fetchone()[0])

    def close(self) -> None:
        self._store.release()


def now_text(clock: Callable[[], float] = time.time) -> str:
    """The current time as RFC 3339 (UTC), as events carry it."""
    return datetime.fromtimestamp(clock(), tz=timezone.utc).isoformat().replace("+00:00", "Z")
