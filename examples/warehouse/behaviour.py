"""The warehouse's Robot Behaviour Service: moves carts with robots it reaches only through bus events.

It never talks ROS. Per robot, a worker takes the next cart from a task table shared in SQLite (atomically:
`BEGIN IMMEDIATE`, so two workers, threads or processes, can never take the same cart), then runs, with RB-1s
(`kind="rb1"`, procedures on services),

    goto picking point → check the cart's marker → pick → goto the door → open the door → goto the zone → place

or with nav_base robots (`kind="nav_base"`, ROS actions: a docking fails when the cart is not there)

    navigateToPose picking point → dockRobot (the cart) → navigateToPose the door → open the door
    → navigateToPose the zone → undockRobot

sending one invoke (or write) event per step and waiting for the step's answer: the terminal feedback of a
mission (or goal), the marker in the robot's `poseMarker` property events, the door's `position` property. It
marks the cart moved and takes the next, until none is left. A failed step marks the cart failed and stops the robot
(the reference behaviour stopped its mission cycle on `unknown`). Every bus message is counted per action.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
import uuid
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from td2adaptor.model import Model
from td2adaptor.model.events import Kind, build_catalog
from td2adaptor.runtime.bus.bus import Bus, Message
from td2adaptor.runtime.events import envelope, loads

SOURCE = "warehouse/behaviour"
KINDS = ("rb1", "nav_base")  # the example robots the behaviour can drive


@dataclass(frozen=True)
class Cart:
    """A cart at a picking point (its AR marker) and the storage zone it belongs in."""

    id: str
    marker: int
    pick: tuple[float, float]
    zone: str
    place: tuple[float, float]


@dataclass
class StepStats:
    """Bus traffic of one kind of step: how often it ran, messages sent and received for it."""

    count: int = 0
    sent: int = 0
    received: int = 0

    @property
    def per_action(self) -> float:
        return (self.sent + self.received) / self.count if self.count else 0.0


@dataclass
class CartResult:
    cart: Cart
    robot: str
    moved: bool
    seconds: float
    failure: str = ""


class StepFailed(Exception):
    """A step ended otherwise than as planned (failed feedback, timeout, refusal); the message says how."""


# ---------------------------------------------------------------------------------------------------------
# the task table


class TaskTable:
    """Carts to move, in SQLite; each worker thread or process uses its own connection."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def connect(self) -> sqlite3.Connection:
        return sqlite3.connect(self.path, isolation_level=None, timeout=30.0)

    def create(self, carts: Sequence[Cart]) -> None:
        with self.connect() as con:
            con.execute(
                "CREATE TABLE IF NOT EXISTS carts (id TEXT PRIMARY KEY, marker INTEGER NOT NULL, "
                "pick_x REAL, pick_y REAL, zone TEXT NOT NULL, place_x REAL, place_y REAL, "
                "state TEXT NOT NULL DEFAULT 'todo' CHECK (state IN ('todo', 'taken', 'moved', 'failed')), "
                "robot TEXT, taken_at REAL, done_at REAL, note TEXT)"
            )
            con.executemany(
                "INSERT OR REPLACE INTO carts (id, marker, pick_x, pick_y, zone, place_x, place_y) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                [(c.id, c.marker, *c.pick, c.zone, *c.place) for c in carts],
            )
        # `with` on a connection only ends a transaction; close it explicitly
        con.close()

    def take(self, con: sqlite3.Connection, robot: str) -> Cart | None:
        """The next cart to move, now `taken` by `robot`; None when none is left. Atomic across processes."""
        con.execute("BEGIN IMMEDIATE")  # the write lock before the read: no other taker can slip in between
        try:
            row = con.execute(
                "SELECT id, marker, pick_x, pick_y, zone, place_x, place_y FROM carts "
                "WHERE state = 'todo' ORDER BY id LIMIT 1"
            ).fetchone()
            if row is not None:
                changed = con.execute(
                    "UPDATE carts SET state = 'taken', robot = ?, taken_at = ? WHERE id = ? AND state = 'todo'",
                    (robot, time.time(), row[0]),
                ).rowcount
                assert changed == 1, "the write lock makes this impossible"
            con.execute("COMMIT")
        except BaseException:
            con.execute("ROLLBACK")
            raise
        if row is None:
            return None
        return Cart(row[0], int(row[1]), (row[2], row[3]), row[4], (row[5], row[6]))

    def finish(self, con: sqlite3.Connection, cart: Cart, *, moved: bool, note: str = "") -> None:
        con.execute(
            "UPDATE carts SET state = ?, done_at = ?, note = ? WHERE id = ? AND state = 'taken'",
            ("moved" if moved else "failed", time.time(), note, cart.id),
        )

    def states(self) -> dict[str, str]:
        con = self.connect()
        try:
            return dict(con.execute("SELECT id, state FROM carts ORDER BY id").fetchall())
        finally:
            con.close()


# ---------------------------------------------------------------------------------------------------------
# the bus side


@dataclass
class _Inbox:
    """Every message received, indexed for the waits: by correlation, by (robot, property)."""

    cond: threading.Condition = field(default_factory=threading.Condition)
    by_correlation: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    latest: dict[tuple[str, str], dict[str, Any]] = field(default_factory=dict)
    arrivals: Counter[tuple[str, str]] = field(default_factory=Counter)
    status: dict[str, str] = field(default_factory=dict)
    received: int = 0
    properties: int = 0


class BehaviourService:
    """Moves the carts of `table` with `robots` (robot ids) and the door `door`, through `bus` only."""

    def __init__(
        self,
        bus: Bus,
        robot_model: Model,
        door_model: Model,
        robots: Sequence[str],
        door: str,
        table: TaskTable,
        *,
        door_front: tuple[float, float],
        mission_timeout: float = 60.0,
        topic_root: str = "td2adaptor",
        log: Callable[[str], None] = lambda _line: None,
        kind: str = "rb1",
    ) -> None:
        if kind not in KINDS:
            raise ValueError(f"robot kind {kind!r}: one of {', '.join(KINDS)}")
        self.kind = kind
        self.bus = bus
        self.robots = list(robots)
        self.door = door
        self.table = table
        self.door_front = door_front
        self.mission_timeout = mission_timeout
        self.root = topic_root
        self.log = log
        self.robot_events = build_catalog(robot_model)
        self.door_events = build_catalog(door_model)
        self.stats: dict[str, StepStats] = {}
        self.sent = 0
        self._inbox = _Inbox()
        self._lock = threading.Lock()
        self._stop = threading.Event()

    # -- bus -----------------------------------------------------------------------------------------------

    def connect(self) -> None:
        r = self.root
        for pattern in (f"{r}/+/status", f"{r}/+/+/+/feedback", f"{r}/+/error"):
            self.bus.subscribe(pattern, self._on_message)
        if self.kind == "rb1":
            for robot in self.robots:
                marker = self.robot_events.find(Kind.PROPERTY, "poseMarker")
                self.bus.subscribe(marker.topic(robot, r), self._on_message)
        self.bus.subscribe(self.door_events.find(Kind.PROPERTY, "position").topic(self.door, r), self._on_message)
        self.bus.connect()

    def _on_message(self, msg: Message) -> None:
        try:
            event = loads(msg.payload)
        except (UnicodeDecodeError, ValueError):
            return
        if not isinstance(event, dict):
            return
        box = self._inbox
        with box.cond:
            box.received += 1
            kind, robot = event.get("type"), event.get("robot")
            correlation = event.get("correlation")
            if kind == "status" and isinstance(robot, str):
                box.status[robot] = str((event.get("payload") or {}).get("state"))
            elif kind == "property" and isinstance(robot, str):
                box.properties += 1
                key = (robot, str(event.get("affordance")))
                box.latest[key] = event
                box.arrivals[key] += 1
            if isinstance(correlation, str):
                box.by_correlation.setdefault(correlation, []).append(event)
            box.cond.notify_all()

    def _send(self, topic: str, event: Mapping[str, Any]) -> None:
        self.bus.publish(topic, json.dumps(event).encode("utf-8"))
        with self._lock:
            self.sent += 1

    def _count(self, step: str, sent: int, received: int) -> None:
        with self._lock:
            stats = self.stats.setdefault(step, StepStats())
            stats.count += 1
            stats.sent += sent
            stats.received += received

    def _wait(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Wait (at most `timeout`, less when stopped) until `predicate` holds; whether it does."""
        with self._inbox.cond:
            self._inbox.cond.wait_for(lambda: self._stop.is_set() or predicate(), timeout)
            return predicate()

    def wait_online(self, timeout: float) -> list[str]:
        """Wait until every robot and the door say `online`; the ones that did not."""
        everyone = [*self.robots, self.door]
        self._wait(lambda: all(self._inbox.status.get(r) == "online" for r in everyone), timeout)
        return [r for r in everyone if self._inbox.status.get(r) != "online"]

    def stop(self) -> None:
        self._stop.set()
        with self._inbox.cond:
            self._inbox.cond.notify_all()

    # -- steps ---------------------------------------------------------------------------------------------

    def _mission(self, robot: str, action: str, payload: Mapping[str, Any]) -> dict[str, Any]:
        """Invoke `action` and wait for its terminal feedback; its payload (StepFailed unless finished)."""
        correlation = f"{robot}-{action}-{uuid.uuid4().hex[:8]}"
        spec = self.robot_events.find(Kind.INVOKE, action)
        event = envelope(Kind.INVOKE, robot=robot, source=SOURCE, payload=payload, affordance=action)
        event["correlation"] = correlation
        self._send(spec.topic(robot, self.root), event)
        box = self._inbox

        def terminal() -> dict[str, Any] | None:
            for e in box.by_correlation.get(correlation, []):
                if e.get("type") == "feedback" and (e.get("payload") or {}).get("terminal"):
                    return e
            return None

        done = self._wait(lambda: terminal() is not None, self.mission_timeout)
        with box.cond:
            answers = list(box.by_correlation.get(correlation, []))
        self._count(action, 1, len(answers))
        end = terminal()
        if not done or end is None:
            raise StepFailed(f"{robot} {action}: no terminal feedback within {self.mission_timeout:g} s")
        result: dict[str, Any] = end["payload"]
        if result.get("state") != "finished":
            why = result.get("message") or result.get("reason") or result.get("state")
            raise StepFailed(f"{robot} {action} {result.get('state')}: {why}")
        return result

    def goto(self, robot: str, where: tuple[float, float]) -> None:
        goal = {"pose": {"x": float(where[0]), "y": float(where[1]), "theta": 0.0}}
        self._mission(robot, "gotoRun", {"procedure": {"goals": [goal]}})

    def check_marker(self, robot: str, marker: int) -> None:
        """Wait until the robot's `poseMarker` property shows `marker` (the reference's CheckMarker)."""
        key = (robot, "poseMarker")
        box = self._inbox
        with box.cond:
            before = box.arrivals[key]

        def seen() -> bool:
            event = box.latest.get(key)
            markers = ((event or {}).get("payload") or {}).get("markers") or []
            return box.arrivals[key] > before and any(m.get("id") == marker for m in markers)

        ok = self._wait(seen, self.mission_timeout)
        with box.cond:
            received = box.arrivals[key] - before
        self._count("poseMarker check", 0, received)
        if not ok:
            raise StepFailed(f"{robot} does not see marker {marker} at the picking point")

    def open_door(self) -> None:
        """Command the door open and wait until its position property says it is."""
        key = (self.door, "position")
        box = self._inbox
        with box.cond:
            before = box.arrivals[key]
        spec = self.door_events.find(Kind.WRITE, "command")
        event = envelope(Kind.WRITE, robot=self.door, source=SOURCE, payload={"data": 1.0}, affordance="command")
        event["correlation"] = f"door-open-{uuid.uuid4().hex[:8]}"
        self._send(spec.topic(self.door, self.root), event)

        def is_open() -> bool:
            value = ((box.latest.get(key) or {}).get("payload") or {}).get("data")
            return isinstance(value, (int, float)) and value >= 0.99

        ok = self._wait(is_open, self.mission_timeout)
        with box.cond:
            received = box.arrivals[key] - before
            errors = [e for e in box.by_correlation.get(event["correlation"], []) if e.get("type") == "error"]
        self._count("door open", 1, received + len(errors))
        if errors:
            raise StepFailed(f"door {self.door}: {errors[0]['payload'].get('message')}")
        if not ok:
            raise StepFailed(f"door {self.door} did not open within {self.mission_timeout:g} s")

    def navigate(self, robot: str, where: tuple[float, float]) -> None:
        """A nav_base's NavigateToPose goal (a PoseStamped in the map frame), to its terminal feedback."""
        pose = {"position": {"x": float(where[0]), "y": float(where[1])}, "orientation": {"w": 1.0}}
        self._mission(robot, "navigateToPose", {"pose": {"header": {"frame_id": "map"}, "pose": pose}})

    def move(self, robot: str, cart: Cart) -> None:
        if self.kind == "nav_base":
            self.navigate(robot, cart.pick)
            self._mission(robot, "dockRobot", {"use_dock_id": True, "dock_id": cart.id})
            self.navigate(robot, self.door_front)
            self.open_door()
            self.navigate(robot, cart.place)
            self._mission(robot, "undockRobot", {})
            return
        frame = {"pick_frame_id": f"{robot}_cart{cart.marker}_contact"}
        self.goto(robot, cart.pick)
        self.check_marker(robot, cart.marker)
        self._mission(robot, "pickRun", {"procedure": frame})
        self.goto(robot, self.door_front)
        self.open_door()
        self.goto(robot, cart.place)
        self._mission(robot, "placeRun", {"procedure": frame})

    # -- workers -------------------------------------------------------------------------------------------

    def worker(self, robot: str, results: list[CartResult]) -> None:
        """Take carts for `robot` until none is left (or a step fails)."""
        con = self.table.connect()
        try:
            while not self._stop.is_set():
                cart = self.table.take(con, robot)
                if cart is None:
                    return
                self.log(f"{robot} takes {cart.id} (marker {cart.marker}) to storage zone {cart.zone}")
                started = time.monotonic()
                try:
                    self.move(robot, cart)
                except StepFailed as exc:
                    self.table.finish(con, cart, moved=False, note=str(exc))
                    results.append(CartResult(cart, robot, False, time.monotonic() - started, str(exc)))
                    self.log(f"{robot}: {cart.id} not moved: {exc}")
                    return
                self.table.finish(con, cart, moved=True)
                results.append(CartResult(cart, robot, True, time.monotonic() - started))
                self.log(f"{robot} stored {cart.id} in zone {cart.zone} ({time.monotonic() - started:.1f} s)")
        finally:
            con.close()

    def run(self, timeout: float) -> list[CartResult]:
        """Every robot works the table in its own thread; the results, in the order carts were finished."""
        results: list[CartResult] = []
        threads = [
            threading.Thread(target=self.worker, args=(robot, results), name=f"behaviour-{robot}", daemon=True)
            for robot in self.robots
        ]
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + timeout
        for thread in threads:
            thread.join(max(0.0, deadline - time.monotonic()))
        if any(t.is_alive() for t in threads):
            self.stop()
            for thread in threads:
                thread.join(5)
        return results

    @property
    def received(self) -> int:
        return self._inbox.received

    @property
    def property_events(self) -> int:
        return self._inbox.properties
