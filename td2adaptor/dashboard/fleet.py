"""What the bus says about each robot, kept by the dashboard's server and handed to the pages watching it.

Fed by the MQTT client's thread: a robot appears with its retained TD on `<root>/<robot>/td` and disappears
when the TD is cleared (a clean stop); its retained status (`<root>/<robot>/status`, the broker's will after a
crash) and its last error (`<root>/<robot>/error`) come on their own topics; property values and events on the
topics its TD names (td2adaptor's TDs put them under `<root>/<robot>/wot-thing/`, subscribed from the start, so
that a page cannot invoke before the answers are heard; a TD naming others gets them subscribed as it arrives,
from a thread of their own: a subscription waits for the broker's answer, which the MQTT thread delivers).
Each page is a `Watcher`: fleet news for every robot, values and events for the one robot it shows; values
coalesce (the latest wins), events never do.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import orjson

from td2adaptor.dashboard.pose import Pose, PosePath, find_pose, read_pose
from td2adaptor.dashboard.tdforms import Affordances, affordances
from td2adaptor.model.wot import WOT_LEVEL
from td2adaptor.runtime.bus.bus import Handler, Message, topic_matches

log = logging.getLogger("td2adaptor.dashboard")

#: events of one robot the server keeps, so that a page opened (or switched back) later shows the missions
EVENTS_KEPT = 300
#: news one page may have pending before the oldest are dropped (values coalesce anyway)
PENDING_KEPT = 10000


class Subscriber(Protocol):
    def subscribe(self, pattern: str, handler: Handler, *, qos: int = 1) -> None: ...


@dataclass
class Robot:
    id: str
    td: dict[str, Any] | None = None
    source: str = "bus"  # where its TD came from: "bus" (retained) or "directory"
    title: str = ""
    status: dict[str, Any] | None = None
    last_error: dict[str, Any] | None = None
    pose_at: tuple[PosePath, ...] = ()
    pose: Pose | None = None
    topics: Affordances = field(default_factory=Affordances)
    values: dict[str, Any] = field(default_factory=dict)
    events: deque[dict[str, Any]] = field(default_factory=lambda: deque(maxlen=EVENTS_KEPT))

    def summary(self) -> dict[str, Any]:
        """What the fleet list shows of the robot (the status payload as it is: its fields may grow)."""
        return {
            "id": self.id,
            "title": self.title,
            "hasTd": self.td is not None,
            "source": self.source,
            "status": self.status,
            "lastError": self.last_error,
            "pose": self.pose,
            "poseProperty": self.pose_at[0].prop if self.pose_at else None,
        }


class Watcher:
    """One page's pending news; `wake` is called (from any thread) when there was none and now is some."""

    def __init__(self, watch: str | None, wake: Callable[[], None]) -> None:
        self.watch = watch
        self._wake = wake
        self._lock = threading.Lock()
        self._ordered: list[dict[str, Any]] = []
        self._latest: dict[tuple[str, str], dict[str, Any]] = {}

    def push(self, item: dict[str, Any], key: tuple[str, str] | None = None) -> None:
        with self._lock:
            empty = not self._ordered and not self._latest
            if key is None:
                self._ordered.append(item)
                if len(self._ordered) > PENDING_KEPT:  # a page that does not read: it keeps the latest
                    del self._ordered[: len(self._ordered) - PENDING_KEPT]
            else:
                self._latest[key] = item
        if empty:
            self._wake()

    def take(self) -> list[dict[str, Any]]:
        with self._lock:
            out = self._ordered + list(self._latest.values())
            self._ordered, self._latest = [], {}
        return out


def _now_ms() -> float:
    return time.time() * 1000.0


def _json(payload: bytes) -> Any:
    try:
        return orjson.loads(payload)
    except orjson.JSONDecodeError:
        return None


class Fleet:
    """The robots on the bus under `root`, and the pages watching them."""

    def __init__(self, root: str = "td2adaptor") -> None:
        self.root = root
        self.robots: dict[str, Robot] = {}
        self._lock = threading.RLock()
        self._watchers: list[Watcher] = []
        self.closing = False  # the server is stopping: streams end
        self._routes: dict[str, tuple[str, str, str]] = {}  # topic -> (robot, "property" | "event", name)
        self._subscribed: set[str] = set()
        self._statuses: dict[str, dict[str, Any]] = {}  # robot -> its last status, also while it has no TD
        self._bus_tds: set[str] = set()  # robots whose TD is retained on the bus
        self._directory: dict[str, dict[str, Any]] = {}  # robot -> its TD in the directory's last listing
        self._bus: Subscriber | None = None
        self._to_subscribe: queue.Queue[str | None] = queue.Queue()
        self._subscriber: threading.Thread | None = None
        self._wot = f"{root}/+/{WOT_LEVEL}/#"  # where td2adaptor's TDs put their affordances' topics

    # -- the bus ---------------------------------------------------------------------------------------------

    def attach(self, bus: Subscriber) -> None:
        """Subscribe to every robot's TD, status and errors (before the bus connects: also after reconnects)."""
        self._bus = bus
        bus.subscribe(f"{self.root}/+/td", self._on_td)
        bus.subscribe(f"{self.root}/+/status", self._on_status)
        bus.subscribe(f"{self.root}/+/error", self._on_error)
        bus.subscribe(self._wot, self._on_affordance)  # what a new TD names is heard at once, without a SUBACK
        self._subscriber = threading.Thread(target=self._subscribe_loop, name="dashboard-subscribe", daemon=True)
        self._subscriber.start()

    def close(self) -> None:
        self._to_subscribe.put(None)

    def _subscribe_loop(self) -> None:
        while (topic := self._to_subscribe.get()) is not None:
            bus = self._bus
            try:
                if bus is not None:
                    bus.subscribe(topic, self._on_affordance)
            except Exception as exc:  # noqa: BLE001 - a robot's bad topic must not end the dashboard
                log.warning("cannot subscribe to %s: %s", topic, exc)

    def _robot_of(self, topic: str) -> str | None:
        levels = topic.split("/")
        return levels[-2] if len(levels) >= 3 and "/".join(levels[:-2]) == self.root else None

    def _on_td(self, msg: Message) -> None:
        robot_id = self._robot_of(msg.topic)
        if robot_id is None:
            return
        td = _json(msg.payload) if msg.payload else None
        with self._lock:
            if not isinstance(td, dict):
                self._bus_tds.discard(robot_id)
                if robot_id in self._directory:
                    self._take(robot_id, self._directory[robot_id], "directory")
                elif robot_id in self.robots:
                    self._forget(robot_id)
                return
            self._bus_tds.add(robot_id)
            self._take(robot_id, td, "bus")

    def directory_tds(self, tds: dict[str, dict[str, Any]]) -> None:
        """The robots a TD directory lists now (robot id -> TD); a robot's TD on the bus wins over these."""
        with self._lock:
            gone = set(self._directory) - set(tds)
            self._directory = dict(tds)
            for robot_id, td in tds.items():
                robot = self.robots.get(robot_id)
                if robot_id not in self._bus_tds and (robot is None or robot.td != td):
                    self._take(robot_id, td, "directory")
            for robot_id in gone - self._bus_tds:
                if robot_id in self.robots:
                    self._forget(robot_id)

    def _take(self, robot_id: str, td: dict[str, Any], source: str) -> None:
        """`td` as the robot's TD (under the lock)."""
        robot = self.robots.setdefault(robot_id, Robot(robot_id))
        robot.td = td
        robot.source = source
        robot.status = self._statuses.get(robot_id)
        robot.title = str(td.get("title") or robot_id)
        robot.topics = affordances(td, f"{self.root}/{robot_id}/")
        robot.pose_at = find_pose(td)
        for topic, name in robot.topics.properties.items():
            self._route(topic, (robot_id, "property", name))
        for topic, name in robot.topics.events.items():
            if topic != f"{self.root}/{robot_id}/status":
                self._route(topic, (robot_id, "event", name))
        self._fleet_news(robot)

    def _route(self, topic: str, route: tuple[str, str, str]) -> None:
        self._routes[topic] = route
        if topic not in self._subscribed and not topic_matches(self._wot, topic):
            self._subscribed.add(topic)
            self._to_subscribe.put(topic)

    def _forget(self, robot_id: str) -> None:
        del self.robots[robot_id]
        for watcher in self._watchers:
            watcher.push({"k": "gone", "robot": robot_id})

    def _on_status(self, msg: Message) -> None:
        robot_id = self._robot_of(msg.topic)
        event = _json(msg.payload) if msg.payload else None
        if robot_id is None or not isinstance(event, dict):
            return
        payload = event.get("payload")
        if event.get("type") != "status" or not isinstance(payload, dict) or not isinstance(payload.get("state"), str):
            return  # not the edge node's: wotpy's read of `presence` publishes {"action": "read"} on this topic
        status = {**payload, "time": event.get("time")}
        with self._lock:
            self._statuses[robot_id] = status
            robot = self.robots.get(robot_id)  # listed only with a TD: a cleanly stopped robot cleared it
            if robot is not None:
                robot.status = status
                self._fleet_news(robot)

    def _on_error(self, msg: Message) -> None:
        robot_id = self._robot_of(msg.topic)
        event = _json(msg.payload)
        if robot_id is None or not isinstance(event, dict):
            return
        payload = event.get("payload")
        with self._lock:
            robot = self.robots.get(robot_id)
            if robot is None or not isinstance(payload, dict):
                return
            robot.last_error = {**payload, "time": event.get("time"), "correlation": event.get("correlation")}
            self._fleet_news(robot)

    def _fleet_news(self, robot: Robot) -> None:
        item = {"k": "robot", "robot": robot.summary()}
        for watcher in self._watchers:
            watcher.push(item)

    def _on_affordance(self, msg: Message) -> None:
        with self._lock:
            route = self._routes.get(msg.topic)
            robot = self.robots.get(route[0]) if route else None
        if route is None or robot is None or not msg.payload:
            return
        data = _json(msg.payload)
        robot_id, kind, name = route
        at = _now_ms()
        with self._lock:
            if kind == "property":
                robot.values[name] = data
                item = {"k": "value", "robot": robot_id, "name": name, "value": data, "t": at}
                pose = read_pose(robot.pose_at, data) if robot.pose_at and robot.pose_at[0].prop == name else None
                if pose is not None:
                    robot.pose = pose
                for watcher in self._watchers:
                    if watcher.watch == robot_id:
                        watcher.push(item, (robot_id, name))
                    if pose is not None:
                        watcher.push({"k": "pose", "robot": robot_id, "pose": pose}, (robot_id, "\0pose"))
            else:
                item = {"k": "event", "robot": robot_id, "name": name, "data": data, "t": at}
                robot.events.append(item)
                for watcher in self._watchers:
                    if watcher.watch == robot_id:
                        watcher.push(item)

    # -- the pages -------------------------------------------------------------------------------------------

    def watch(self, watch: str | None, wake: Callable[[], None]) -> tuple[Watcher, dict[str, Any]]:
        """A new page's watcher and its first message: every robot, and the watched one's values and events."""
        watcher = Watcher(watch, wake)
        with self._lock:
            self._watchers.append(watcher)
            snapshot: dict[str, Any] = {"k": "snapshot", "robots": [r.summary() for r in self.robots.values()]}
            robot = self.robots.get(watch) if watch else None
            if robot is not None:
                snapshot["values"] = dict(robot.values)
                snapshot["events"] = list(robot.events)
        return watcher, snapshot

    def shutdown(self) -> None:
        """The server is stopping: every page's stream ends (the browser reconnects to whatever comes next)."""
        with self._lock:
            self.closing = True
            watchers = list(self._watchers)
        for watcher in watchers:
            watcher.push({"k": "bye"})

    def unwatch(self, watcher: Watcher) -> None:
        with self._lock:
            if watcher in self._watchers:
                self._watchers.remove(watcher)

    def td(self, robot_id: str) -> dict[str, Any] | None:
        with self._lock:
            robot = self.robots.get(robot_id)
            return robot.td if robot else None

    def topic_for(self, robot_id: str, affordance: str, op: str) -> str | None:
        """The topic the robot's TD names for `op` (a TD 1.1 operation) of `affordance`, if any."""
        with self._lock:
            robot = self.robots.get(robot_id)
            return robot.topics.publish.get((affordance, op)) if robot else None

    def summaries(self) -> list[dict[str, Any]]:
        with self._lock:
            return [r.summary() for r in self.robots.values()]
