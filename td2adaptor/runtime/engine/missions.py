"""Which mission each component of a robot runs, behind one lock.

The engine's loop admits an invoke (one mission per component at a time: a second one is refused `busy`) and
hands cancel events to the mission they are for; whoever follows the mission (a procedure's or a goal's state
machine on the loop, procedure.py and goals.py) takes those cancels and ends the mission once;
queries without a mission id ask about the action's current mission, else the last one the robot named;
stopping waits until nobody follows a mission any more. All of that goes through a `MissionTable` the engine
hands to its runners and its outbox, so no module reaches into another's dictionaries and lock. The loop's
thread is the table's owner; the lock is there for the pool threads that end a procedure mission as they read
the robot's answer (outbox.py's `finish`), and for stopping, which waits from the node's thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from td2adaptor.model import Procedure


@dataclass
class Mission:
    component: str
    action: str
    procedure: Procedure
    correlation: str | None
    payload: Mapping[str, Any]
    started: float
    mission_id: int | None = None
    state: str | None = None
    seq: int = 0
    done: bool = False
    cancels: list[str | None] = field(default_factory=list)
    goal: str | None = None  # a ROS action goal: its id, once the server accepted it
    key: str | None = None  # its row in the ledger (None: not recorded)
    reserved: int = 0  # the ledger's bound on the feedback numbers published


class MissionTable:
    """The mission of each busy component, the last mission id of each action and who still follows a
    mission (each holds an event it sets when it is done), under one lock. `done` and `cancels` of the
    missions in it are written under that lock too; a mission's other fields belong to whoever follows it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._active: dict[str, Mission] = {}
        self._last: dict[str, int] = {}
        self._held: set[threading.Event] = set()  # set when its mission's thread is done with it

    def claim(self, m: Mission, held: threading.Event) -> Mission | None:
        """Make `m` its component's mission, followed by someone who sets `held` when done with it; when the
        component is busy, the mission it runs instead (and nothing changes)."""
        with self._lock:
            busy = self._active.get(m.component)
            if busy is None:
                self._active[m.component] = m
                self._held.add(held)
            return busy

    def release(self, held: threading.Event) -> None:
        """A mission's follower is done with it (it sets `held` next)."""
        with self._lock:
            self._held.discard(held)

    def end(self, m: Mission) -> list[str | None] | None:
        """Mark `m` done and free its component (remembering its mission id for its action); the cancels that
        came as it ended, which its end answers. None when it had ended already: nothing to publish."""
        with self._lock:
            if m.done:
                return None
            m.done = True
            if self._active.get(m.component) is m:
                del self._active[m.component]
            if m.mission_id is not None:
                self._last[m.action] = m.mission_id
            late, m.cancels = m.cancels, []
            return late

    def find(self, component: str, match: Callable[[Mission], bool]) -> Mission | None:
        """The mission `component` runs, if `match` accepts it."""
        with self._lock:
            m = self._active.get(component)
            return m if m is not None and match(m) else None

    def add_cancel(self, component: str, correlation: str | None, match: Callable[[Mission], bool]) -> Mission | None:
        """Hand a cancel event to the mission `component` runs, if `match` accepts it: that mission, else None."""
        with self._lock:
            m = self._active.get(component)
            if m is None or not match(m):
                return None
            m.cancels.append(correlation)
            return m

    def take_cancels(self, m: Mission) -> list[str | None]:
        """The cancel events handed to `m` since the last call (its follower carries them out)."""
        with self._lock:
            requests, m.cancels = m.cancels, []
            return requests

    def mission_id(self, action: str) -> int:
        """The id of `action`'s mission in progress, else of its last one; -1 (the robot's "last one") if none."""
        with self._lock:
            for m in self._active.values():
                if m.action == action and m.mission_id is not None:
                    return m.mission_id
            return self._last.get(action, -1)

    def running(self) -> list[Mission]:
        with self._lock:
            return list(self._active.values())

    def held(self) -> list[threading.Event]:
        """The events of the followers still following a mission (stopping waits for them)."""
        with self._lock:
            return list(self._held)

    def idle(self) -> bool:
        with self._lock:
            return not self._active
