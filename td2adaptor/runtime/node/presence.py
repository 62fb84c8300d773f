"""Is the robot's ROS side there? What the edge node sees of the servers of a robot's actions.

A robot's edge node can be up while the robot is not (its ROS nodes stopped, crashed, or not started yet): the
robot's status then says `online` and `robot: absent`, and an invoke is answered at once (engine.py, error
`absent`) instead of after `call_timeout`. A `Probe` looks at the servers the way the port reaches them, cheaply
(no call is made):

* ROS 2 (a `GeneratedPort` on rclpy): each service of the robot and each ROS action's `_action/send_goal` (the
  names from the model, as for ROS 1) has a server in its node's graph cache (DDS discovery): the services
  the graph's nodes serve, read node by node once per `GRAPH_FRESH` for every robot of the node, and for a
  name not among them its servers counted (`count_services`); a server that stops cleanly is gone at once,
  one killed (SIGKILL, power) when DDS drops its participant (its lease: Fast DDS's default is 20 s);
* the simulated robot (`SimPort`): its `down` switch, when the test sets `watched`;
* ROS 1 (rospy here, or the bridge): the ROS 1 master's `getSystemState`, one XML-RPC call per master and
  period for all its robots: each service has a provider, each actionlib server publishes its `status`, and
  that node runs (a clean stop unregisters at once; a killed node, which stays registered, is found dead by
  a connection to its XML-RPC API that is refused: ros1nodes.py);
* anything else: no probe; the status has no `robot` member and nothing is refused.

`Presence` keeps what the last look saw. An action whose server has never been seen is refused only once the
node has run longer than `grace` (its calls' own wait for a server): at start-up, discovery takes a moment,
and an invoke then waits for the server as it always did. The word is not known (`word()` None: the status has
no `robot` member) only while discovery may still be finding the servers: for `DISCOVERY_SETTLE` seconds at
most (or `grace`, when shorter). Without it a robot that is there said `absent` for the first second or two of
every start; with `grace` instead, one that is not there had no word for `call_timeout` (10 s: a restart that
found no robot).
"""

from __future__ import annotations

import os
import threading
import time
import weakref
import xmlrpc.client
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from td2adaptor.model.events import PRESENCE_WORDS, EventSpec
from td2adaptor.runtime.node.ros1nodes import TimeoutTransport, alive

#: what a look at the robot's ROS side says: each action (TD affordance) and whether its server is there
Probe = Callable[[], Mapping[str, bool]]
#: seconds ROS 2 discovery may take at start-up to show a robot's servers that are there (typically within a
#: second or two): an unseen server counts as `absent` in the status after this, not after `call_timeout`
DISCOVERY_SETTLE = 2.0
PRESENT, PARTIAL, ABSENT = PRESENCE_WORDS


def ros_names(
    model: Any, namespace: str, actions: Iterable[str], server_suffix: str
) -> tuple[dict[str, str], dict[str, str]]:
    """The graph names a look checks, by TD action: each ROS service's, and each ROS action's with
    `server_suffix` (a name its server offers: ROS 1's `/status` topic, ROS 2's `/_action/send_goal` service)."""
    wanted = set(actions)
    services: dict[str, str] = {}
    servers: dict[str, str] = {}
    for component in model.components:
        for service in component.services:
            if service.name in wanted:
                services[service.name] = "/" + service.ros_name.resolve(namespace).lstrip("/")
        for action in component.actions:
            if action.name in wanted:
                servers[action.name] = "/" + action.ros_name.resolve(namespace).lstrip("/") + server_suffix
    return services, servers


#: how long one read of a node's ROS 2 graph (what each of its nodes serves) serves every robot of that node, at
#: least; and at most this share of the time is spent reading (a graph of many nodes is read less often)
GRAPH_FRESH, GRAPH_SHARE = 0.25, 0.1
#: by node: when its graph was read, the services served, and until when that read serves
_graphs: weakref.WeakKeyDictionary[Any, tuple[float, frozenset[str], float]] = weakref.WeakKeyDictionary()
_readers: weakref.WeakKeyDictionary[Any, threading.Lock] = weakref.WeakKeyDictionary()  # held while reading it
_graphs_lock = threading.Lock()


def graph_served(node: Any, clock: Callable[[], float] = time.monotonic) -> frozenset[str]:
    """The services the nodes of `node`'s ROS 2 graph serve (fully qualified, the actions' hidden
    `_action/...` ones too), read node by node (`get_service_names_and_types_by_node`: servers only, where the
    graph's plain list also names a service only clients ask for, ours) once per `GRAPH_FRESH` for every robot
    of `node`: counting the servers of each name (a scan of the whole graph cache each) cost the looks of 100
    RB-1s about a tenth of a core. A read serves for `GRAPH_FRESH`, or for ten times what it took when that is
    longer (a read by node looks the node up among all of the graph's: the reads grow with its square). While
    one look reads the graph, the others take the last read instead of waiting (a look runs on the call pool,
    whose threads make the robots' calls); only the first read is waited for. Raises when the node cannot be
    asked (shut down)."""
    with _graphs_lock:
        known = _graphs.get(node)
        if known is not None and clock() - known[0] < known[2]:
            return known[1]
        reader = _readers.setdefault(node, threading.Lock())
    if not reader.acquire(blocking=known is None):
        assert known is not None
        return known[1]  # another look is reading it now
    try:
        with _graphs_lock:  # read by the look that held the reader just now?
            known = _graphs.get(node)
            now = clock()
            if known is not None and now - known[0] < known[2]:
                return known[1]
        served: set[str] = set()
        for name, namespace in set(node.get_node_names_and_namespaces()):
            try:
                served.update(
                    str(service) for service, _types in node.get_service_names_and_types_by_node(name, namespace)
                )
            except Exception:  # noqa: BLE001 - that node left the graph since it was listed: it serves nothing
                continue
        read = frozenset(served)
        with _graphs_lock:
            _graphs[node] = (now, read, max(GRAPH_FRESH, (clock() - now) / GRAPH_SHARE))
        return read
    finally:
        reader.release()


#: the probes that never wait on the network (a ROS 2 graph read in the process, the simulated robot's switch)
_QUICK: weakref.WeakSet[Callable[[], Mapping[str, bool]]] = weakref.WeakSet()


def quick(probe: Probe) -> bool:
    """Whether `probe` never waits on the network, so that the looks of many robots may be made one after the
    other on one thread (status.py); a ROS 1 look asks its master over XML-RPC (up to `MASTER_TIMEOUT`)."""
    return probe in _QUICK


def ros2_probe(model: Any, namespace: str, node: Any, actions: Iterable[str]) -> Probe | None:
    """The look at a ROS 2 robot through the graph of the node its port uses: each service of `actions` has a
    server, and each ROS action's `_action/send_goal` service has one (every rclpy and rclcpp action server
    offers it); the names come from the model, as for ROS 1. A name some node of the graph serves
    (`graph_served`, one read shared by the robots) is there; any other has its servers counted
    (`count_services`): a node restarted under its old name while the killed one is still in the graph (until
    its lease ends) is hidden behind the dead one's entry from a read by node, which finds the first node of a
    name only, but its servers are counted."""
    services, servers = ros_names(model, namespace, actions, "/_action/send_goal")
    names = {**services, **servers}
    if not names:
        return None

    def look() -> dict[str, bool]:
        try:
            served = graph_served(node)
            return {name: ros in served or node.count_services(ros) > 0 for name, ros in names.items()}
        except Exception:  # noqa: BLE001 - a node or context shut down: the servers count as gone
            return dict.fromkeys(names, False)

    _QUICK.add(look)
    return look


def sim_probe(port: Any, actions: Iterable[str]) -> Probe:
    """The simulated robot's `down` switch: every action's server gone, or every one there."""
    names = list(actions)

    def look() -> dict[str, bool]:
        return dict.fromkeys(names, not port.down)

    _QUICK.add(look)
    return look


#: seconds one look at a ROS 1 master may take; and how long its answer serves every robot on that master
MASTER_TIMEOUT, MASTER_FRESH = 2.0, 0.2
#: by name: the nodes that provide a service, or publish a topic
Providers = Mapping[str, tuple[str, ...]]
_masters: dict[str, tuple[float, Providers, Providers] | None] = {}
_masters_lock = threading.Lock()


def master_state(uri: str, clock: Callable[[], float] = time.monotonic) -> tuple[Providers, Providers] | None:
    """The nodes the ROS 1 master at `uri` lists as each service's provider and each topic's publishers
    (`getSystemState`, shared by every robot of that master for `MASTER_FRESH`); None when it does not answer."""
    with _masters_lock:
        known = _masters.get(uri)
        if known is not None and clock() - known[0] < MASTER_FRESH:
            return known[1], known[2]
    answer: Any = None
    try:
        with xmlrpc.client.ServerProxy(uri, transport=TimeoutTransport(MASTER_TIMEOUT)) as master:
            answer = master.getSystemState("/td2adaptor_presence")
    except (OSError, xmlrpc.client.Error):
        answer = None
    try:
        code, _message, (publishers, _subscribers, services) = answer
        served = {str(name): tuple(str(n) for n in providers) for name, providers in services if providers}
        published = {str(name): tuple(str(n) for n in nodes) for name, nodes in publishers if nodes}
    except (TypeError, ValueError):  # no answer, or not the master's
        code = 0
    if code != 1:
        with _masters_lock:
            _masters.pop(uri, None)
        return None
    with _masters_lock:
        _masters[uri] = (clock(), served, published)
    return served, published


def ros1_probe(model: Any, namespace: str, master: str, actions: Iterable[str]) -> Probe | None:
    """The look at a ROS 1 robot through its master (whatever reaches it: rospy here or the bridge): each
    service of `actions` has a provider, each actionlib server publishes its `status`, and that node runs
    (ros1nodes.py: a killed node stays listed by the master). A master that does not answer: every server is
    gone (the robot's ROS side cannot be reached)."""
    services, servers = ros_names(model, namespace, actions, "/status")
    if not services and not servers:
        return None

    def look() -> dict[str, bool]:
        state = master_state(master)
        if state is None:
            return dict.fromkeys([*services, *servers], False)
        served, published = state
        nodes = {name: served.get(ros, ()) for name, ros in services.items()}
        nodes.update({name: published.get(topic, ()) for name, topic in servers.items()})
        running = alive(master, (node for listed in nodes.values() for node in listed))
        return {name: any(node in running for node in listed) for name, listed in nodes.items()}

    return look


def probe_of(port: Any, actions: Iterable[str], model: Any = None, config: Any = None) -> Probe | None:
    """How to look at `port`'s robot (see the module docstring); None when it cannot be told. `model` and
    `config` (the robot's `RuntimeConfig`): for a ROS 1 robot, its names and its master."""
    from td2adaptor.runtime.ros.simport import SimPort

    if isinstance(port, SimPort):
        return sim_probe(port, actions) if port.watched else None
    distro = getattr(port, "distro", None)
    if distro == "ros2" and model is not None and config is not None and getattr(port, "node", None) is not None:
        return ros2_probe(model, config.ros_namespace, port.node, actions)
    if distro == "ros1" and model is not None and config is not None:
        master = config.ros_master_uri or os.environ.get("ROS_MASTER_URI")
        return ros1_probe(model, config.ros_namespace, master, actions) if master else None
    return None


class Presence:
    """What the last look saw (`update`) and what follows from it: the status word, the missing actions, and
    whether an invoke of an action is refused (`absent`). Used on the engine's loop only."""

    def __init__(
        self, robot: str, grace: float, clock: Callable[[], float] = time.monotonic, settle: float | None = None
    ) -> None:
        self.robot = robot
        self.grace = grace
        self.settle = grace if settle is None else min(settle, grace)  # how long the word may wait for discovery
        self.clock = clock
        self.started = clock()
        self.ready: dict[str, bool] | None = None  # None: not looked yet
        self._seen: set[str] = set()  # actions whose server was there once
        self._gone: dict[str, float] = {}  # since when each missing action's server is gone (the loop's clock)

    def update(self, ready: Mapping[str, bool]) -> None:
        now = self.clock()
        self.ready = dict(ready)
        for name, there in ready.items():
            if there:
                self._seen.add(name)
                self._gone.pop(name, None)
            else:
                self._gone.setdefault(name, now)

    def word(self) -> str | None:
        """`present`, `partial` or `absent`; None before the first look, and while an action's server was never
        seen within `settle` of the start (not discovered yet, as `absent` says: not known to be gone)."""
        if self.ready is None or self._discovering():
            return None
        there = sum(self.ready.values())
        return PRESENT if there == len(self.ready) else ABSENT if there == 0 else PARTIAL

    def _discovering(self) -> bool:
        ready = self.ready or {}
        unseen = any(not there and name not in self._seen for name, there in ready.items())
        return unseen and self.clock() - self.started < self.settle

    def missing(self) -> list[str]:
        return sorted(name for name, there in (self.ready or {}).items() if not there)

    def absent(self, spec: EventSpec) -> str | None:
        """(the engine's gate) Why an invoke of `spec`'s action is not sent now, or None."""
        name = spec.affordance
        if self.ready is None or name is None or self.ready.get(name, True):
            return None
        if name not in self._seen and self.clock() - self.started < self.grace:
            return None  # not discovered yet at start-up: the call waits for its server as before
        return (
            f"not sent: the ROS server of {name} is not there (robot {self.robot}'s ROS side is "
            f"{self.word()}); the robot's status says when it is back"
        )
