"""`td2adaptor run --discover`: serve every robot of the Thing Model that shows up in the ROS graph.

A robot is a namespace under which the graph shows the model's interfaces (`Signature`): a server for every
service and action the model names under `{{robotName}}`, or, for a model without any, a publisher of every
topic it subscribes to there. The edge node's own clients and subscriptions never count (servers and
publishers only). Every `period`, at once when a shared fleet asks (`look_now`), and on ROS 2 within `GRAPH_GAP`
of a change of the graph's nodes (`Ros2Graph.stamp`), the watcher reads the graph once and hands the robots it
saw, with those gone for less than `grace` seconds, to the fleet (`Fleet.apply`, origin "discovery"): a new
robot joins, one gone for `grace` leaves (its missions in flight end, its TD is
cleared, its status goes `offline`).

Reading the graph: on ROS 2 with rclpy's graph API on a node of the edge node's own context (no executor:
graph queries need none): the service names once, then, for each namespace that has them all, whether each
has a server (`count_services`); a robot served already is checked by its first interface only (a robot's
servers go together when its process ends). On ROS 1 one `getSystemState` of the master over XML-RPC, whose
service list names servers only, and a look whether each robot's first server still runs (a killed node stays
listed: ros1nodes.py). A robot that cannot be started (a namespace the package refuses) is
retried after `RETRY` seconds, not every period.

In a fleet shared by several processes (`run --share`, share.py) the robots seen go to the share instead of the
fleet: each process lists what it sees, and the share gives each robot to one of the processes that see it.
"""

from __future__ import annotations

import logging
import re
import socket
import threading
import time
import urllib.parse
import xmlrpc.client
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from td2adaptor.model import Model, Role
from td2adaptor.model.events import ALL_ROBOTS, ROBOT_ID
from td2adaptor.runtime.config import ConfigError, RuntimeConfig
from td2adaptor.runtime.node.fleet import Changes
from td2adaptor.runtime.node.ros1nodes import TimeoutTransport, alive
from td2adaptor.runtime.ros.words import DEFAULT_MASTER, master_silent

log = logging.getLogger("td2adaptor.runtime.fleet")

PERIOD = 0.5  # seconds between two readings of the graph
#: seconds between two glances at a graph's nodes (`stamp`, far cheaper than a reading); after a change the graph
#: is read at once, and again `TRAIL` seconds later (a process's node reaches the graph a moment before its
#: interfaces, DDS tells each process of them one by one)
GRAPH_GAP = 0.1
TRAIL = (0.1, 0.3)
RETRY = 30.0  # seconds before a robot that could not be started is tried again
CALLER_ID = "/td2adaptor_discovery"


@dataclass(frozen=True)
class Signature:
    """What shows a robot of the model in a graph: paths under its namespace (without the leading '/')."""

    services: tuple[str, ...]  # served by the robot
    actions: tuple[str, ...]  # ROS 2 action servers
    published: tuple[str, ...]  # topics the robot publishes (used only when the model has no service or action)

    @property
    def empty(self) -> bool:
        return not (self.services or self.actions or self.published)


def signature(model: Model) -> Signature:
    """The model's namespaced interfaces (raises `ConfigError` when there is none: robots cannot be told apart)."""
    services = sorted({s.ros_name.path for c in model.components for s in c.services if s.ros_name.namespaced})
    actions = sorted({a.ros_name.path for c in model.components for a in c.actions if a.ros_name.namespaced})
    published = sorted(
        {
            t.ros_name.path
            for c in model.components
            for t in c.topics
            if t.ros_name.namespaced and t.role is Role.SUBSCRIBER
        }
    )
    sig = Signature(tuple(services), tuple(actions), () if services or actions else tuple(published))
    if sig.empty:
        raise ConfigError(
            "discovery needs a Thing Model whose ROS names live under {{robotName}} (the robot's namespace): "
            "this one names none, so robots cannot be told apart in the ROS graph"
        )
    return sig


def namespaces(names: Iterable[str], path: str) -> set[str]:
    """The namespaces (without slashes around) under which `path` occurs among the graph `names`."""
    tail = "/" + path
    return {n[1 : -len(tail)] for n in names if n.endswith(tail) and len(n) > len(tail) + 1 and n.startswith("/")}


def robot_id(namespace: str) -> str | None:
    """The robot id of a namespace: itself, with '/' between levels as '.'; None when that is no robot id."""
    rid = namespace.strip("/").replace("/", ".")
    return rid if ROBOT_ID.match(rid) and rid != ALL_ROBOTS else None


class Graph(Protocol):
    #: which graph this is, the same in every process that reads it ("" when unknown): a shared fleet's process
    #: on another graph cannot see the robots this one finds (share.py `_heard`)
    name: str

    def robots(self, sig: Signature, known: set[str]) -> set[str]:
        """The namespaces that show `sig` now; `known` ones (served already) may be checked more cheaply."""
        ...


class Ros2Graph:
    """The ROS 2 graph as `node` (an rclpy node, not spun) sees it."""

    def __init__(self, node: Any, name: str = "") -> None:
        self.node = node
        self.name = name

    def stamp(self) -> Any:
        """What changes when a node joins or leaves the graph (a robot's process starts or stops): its nodes. A
        glance costs a small part of a reading (`robots`, which lists every service of the graph), so discovery
        glances every `GRAPH_GAP` and reads the graph when the glance changed, rather than reading it more often:
        a robot found only at the next `PERIOD` waited a quarter of a second on average (issue 32). rclpy gives
        no handle on the graph's own guard condition, and the rmw's `ros_discovery_info` topic, which says each
        change, has a DDS name no rclpy subscription can take (rcl makes every name absolute)."""
        return frozenset(self.node.get_node_names_and_namespaces())

    def robots(self, sig: Signature, known: set[str]) -> set[str]:
        if sig.services or sig.actions:
            names = [n for n, _ in self.node.get_service_names_and_types()]
            paths = [*sig.services, *(f"{a}/_action/send_goal" for a in sig.actions)]
            count = self.node.count_services
        else:
            names = [n for n, _ in self.node.get_topic_names_and_types()]
            paths = list(sig.published)
            count = self.node.count_publishers
        candidates = set.intersection(*(namespaces(names, p) for p in paths))
        found = set()
        for ns in candidates:
            wanted = paths[:1] if ns in known else paths
            if all(count(f"/{ns}/{p}") > 0 for p in wanted):
                found.add(ns)
        return found


class Ros1Graph:
    """The ROS 1 graph as its master knows it (XML-RPC, no rospy needed)."""

    def __init__(self, master_uri: str, timeout: float = 2.0) -> None:
        self.master_uri = master_uri
        self.timeout = timeout
        self.name = f"ros1 {master_uri}"

    def robots(self, sig: Signature, known: set[str]) -> set[str]:
        """The namespaces that show `sig`, whose first interface's node runs: a killed node stays registered
        with the master (ros1nodes.py), and its robot would be served for ever."""
        transport = TimeoutTransport(self.timeout)
        master: Any = xmlrpc.client.ServerProxy(self.master_uri, transport=transport)
        try:
            code, message, state = master.getSystemState(CALLER_ID)
        except OSError as exc:  # said once by the watcher, so say which master and how to name another
            raise OSError(master_silent(self.master_uri, exc)) from exc
        if code != 1:
            raise OSError(f"the ROS 1 master refused getSystemState: {message}")
        publishers, _subscribers, services = state
        if sig.services:
            listed, paths = services, list(sig.services)
        else:  # ROS 1 has no actions here: the topics the robot publishes
            listed, paths = publishers, list(sig.published)
        nodes = {str(name): tuple(str(n) for n in providers) for name, providers in listed if providers}
        if not paths:
            return set()
        found = set.intersection(*(namespaces(nodes, p) for p in paths))
        first = {ns: nodes[f"/{ns}/{paths[0]}"] for ns in found}
        running = alive(self.master_uri, (node for listed_by in first.values() for node in listed_by))
        return {ns for ns, listed_by in first.items() if any(node in running for node in listed_by)}


class Robots(Protocol):
    """What discovery hands its robots to: the process's fleet (fleet.py), or its share of one (share.py)."""

    def robots(self, origin: str | None = None) -> dict[str, RuntimeConfig]: ...

    def origin(self, robot: str) -> str | None: ...

    def apply(self, configs: list[RuntimeConfig], origin: str) -> Changes: ...


class Discovery:
    """Keeps the fleet's discovered robots what `graph` shows (see the module docstring)."""

    def __init__(
        self,
        fleet: Robots,
        graph: Graph,
        sig: Signature,
        make_config: Callable[[str, str], RuntimeConfig],
        *,
        grace: float,
        period: float = PERIOD,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.fleet = fleet
        self.graph = graph
        self.sig = sig
        self.make_config = make_config  # (robot id, namespace) -> its configuration
        self.grace = grace
        self.period = period
        self.clock = clock
        self.scans = 0
        #: hooks told after each reading of the graph, with when it began (this process's monotonic clock): a
        #: shared fleet says then which robots the others see that this process does not (share.py, `unseen`)
        self.on_look: list[Callable[[float], None]] = []
        self._seen: dict[str, tuple[str, float]] = {}  # robot id -> (namespace, when last seen)
        #: robot id -> when a look first did not see it: it leaves once gone that long (`grace`), counted from
        #: the first look without it, not from the last one with it (looks delayed by a long start of other
        #: robots made a robot gone for a moment count as gone for the whole delay)
        self._missing: dict[str, float] = {}
        self._failed: dict[str, float] = {}  # robot id -> when it may be tried again
        self._graph_failing = False
        self._stop = threading.Event()
        self._kick = threading.Event()  # look now rather than at the end of the period (`look_now`)
        self._kicks: list[float] = []  # when to look again, sooner than the period (`look_now` with a delay)
        self._kicks_lock = threading.Lock()
        #: the graph's `stamp` at the last look or glance (a graph without one is read every period only)
        self._stamp: Any = None
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="fleet-discovery", daemon=True)
        self._thread.start()

    def look_now(self, *later: float) -> None:
        """Read the graph again at once, and again `later` seconds from now, not at the end of the period: another
        process of a shared fleet lists a robot this one does not, and every process that can see it should say so
        before it is given out (its own graph may show it a moment later than the other's)."""
        with self._kicks_lock:
            now = time.monotonic()
            self._kicks = sorted([*self._kicks, *(now + d for d in later)])
        self._kick.set()

    def stop(self, timeout: float = 10.0) -> None:
        self._stop.set()
        self._kick.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def _run(self) -> None:
        stamp = getattr(self.graph, "stamp", None)
        while not self._stop.is_set():
            if callable(stamp):
                self._changed(stamp)  # what the look reads (a node that comes during it: the next glance)
            try:
                self.scan()
            except Exception:  # a bug must not end discovery for good
                log.exception("discovery: a scan failed")
            self._wait(time.monotonic() + self.period, stamp if callable(stamp) else None)

    def _wait(self, until: float, stamp: Callable[[], Any] | None) -> None:
        """Until `until` (the period's end), a kick (`look_now`), a change of the graph's nodes a glance saw
        (`stamp`: then looks `TRAIL` seconds later too), or the stop."""
        while not self._stop.is_set():
            with self._kicks_lock:
                now = time.monotonic()
                due = min([until, *self._kicks[:1]])
                if due <= now:
                    self._kicks = [t for t in self._kicks if t > now]
                    return
            glance = stamp is not None and due - now > GRAPH_GAP
            if self._kick.wait(GRAPH_GAP if glance else due - now):
                self._kick.clear()
                return
            if glance and stamp is not None and self._changed(stamp):
                with self._kicks_lock:  # not `look_now`: its kick would make a second look at once
                    now = time.monotonic()
                    self._kicks = sorted([*self._kicks, *(now + d for d in TRAIL)])
                return

    def _changed(self, stamp: Callable[[], Any]) -> bool:
        """Whether the graph's nodes changed since the last look or glance."""
        try:
            now = stamp()
        except Exception:  # noqa: BLE001 - the graph cannot be read now: the period's reading says why
            return False
        changed = self._stamp is not None and now != self._stamp
        self._stamp = now
        return changed

    def scan(self) -> None:
        """One reading of the graph, applied to the fleet; then the `on_look` hooks."""
        began = time.monotonic()
        if self._look():
            for hook in list(self.on_look):
                hook(began)

    def _look(self) -> bool:
        """One reading of the graph, applied to the fleet; False when the graph could not be read."""
        now = self.clock()
        known = {ns for ns, _ in self._seen.values()}
        try:
            present = self.graph.robots(self.sig, known)
        except OSError as exc:  # the ROS 1 master is away: nobody is taken as gone for that
            if not self._graph_failing:
                log.warning("discovery: the ROS graph cannot be read (%s); trying again", exc)
            self._graph_failing = True
            return False
        if self._graph_failing:
            log.info("discovery: the ROS graph can be read again")
        self._graph_failing = False
        self.scans += 1
        for ns in present:
            rid = robot_id(ns)
            if rid is not None:
                self._seen[rid] = (ns, now)
                self._missing.pop(rid, None)
        for rid, (_ns, t) in self._seen.items():
            if t != now:
                self._missing.setdefault(rid, now)
        self._seen = {r: v for r, v in self._seen.items() if now - self._missing.get(r, now) < self.grace}
        self._missing = {r: t for r, t in self._missing.items() if r in self._seen}
        served = self.fleet.robots("discovery")
        others = {c.ros_namespace.strip("/") for r, c in self.fleet.robots().items() if r not in served}
        wanted: dict[str, RuntimeConfig] = {}
        for rid, (ns, _) in self._seen.items():
            if self._failed.get(rid, now) > now or ns in others or self.fleet.origin(rid) not in (None, "discovery"):
                continue  # to be tried again later, or served already from the fleet file or an admin request
            try:
                wanted[rid] = self.make_config(rid, ns)
            except ConfigError as exc:
                log.error("discovery: robot %s (namespace /%s) not served: %s", rid, ns, exc)
                self._failed[rid] = now + RETRY
        if set(wanted) == set(served):
            return True
        changes = self.fleet.apply(list(wanted.values()), "discovery")
        for rid, why in changes.failed.items():
            log.error("discovery: robot %s not served, tried again in %g s: %s", rid, RETRY, why)
            self._failed[rid] = now + RETRY
        for rid in changes.added:
            self._failed.pop(rid, None)
        if changes.added or changes.removed:
            log.info("discovery: %s", changes.describe())
        return True


def ros2_graph(graph_node: Callable[[int | None], Any], domain: int | None, env: Mapping[str, str]) -> Graph:
    """The ROS 2 graph of `domain` (None: the environment's). Its name is the domain, and this host's name when
    discovery stays on the host (`ROS_LOCALHOST_ONLY`, `ROS_AUTOMATIC_DISCOVERY_RANGE`)."""
    number = domain if domain is not None else env.get("ROS_DOMAIN_ID", "").strip() or "0"
    local = env.get("ROS_LOCALHOST_ONLY") == "1" or env.get("ROS_AUTOMATIC_DISCOVERY_RANGE") in ("LOCALHOST", "OFF")
    return Ros2Graph(graph_node(domain), f"ros2 domain {number}" + (f" on {socket.gethostname()}" if local else ""))


def ros1_graph(master_uri: str | None, env: Mapping[str, str]) -> Graph:
    """The ROS 1 graph of the master at `master_uri` (None: `ROS_MASTER_URI`, else ROS's default). Its name is
    the master's host and port, however the URI spells them, and this host's name for a loopback master: the
    processes of a shared fleet compare the names to tell whether they read one graph."""
    uri = master_uri or env.get("ROS_MASTER_URI") or DEFAULT_MASTER
    if not re.match(r"^https?://", uri):
        raise ConfigError(f"ROS master URI {uri!r} must be http://host:port")
    try:
        parts = urllib.parse.urlsplit(uri)
        host, port = (parts.hostname or "localhost").lower(), parts.port or 11311
    except ValueError as exc:
        raise ConfigError(f"ROS master URI {uri!r} must be http://host:port") from exc
    graph = Ros1Graph(uri)
    if host == "localhost" or host == "::1" or host.startswith("127."):
        graph.name = f"ros1 master localhost:{port} on {socket.gethostname()}"
    else:
        graph.name = f"ros1 master {host}:{port}"
    return graph
