"""One edge-node process of a shared fleet (node/share.py), its robots simulated (`SimPort`), so a test can run
three and kill one: `python -m tests.runtime.share_proc URL STATE_DIR ROBOTS RUNS_FILE [own]`; `own`: a state
directory of its own under STATE_DIR, as a process on another host has.

Every mission a robot starts is appended to RUNS_FILE as `<robot> <x>` (the goal's x, unique per invoke in the
tests) by whichever process runs it: the tests count runs across processes from it. SIGTERM stops it cleanly.
With `SHARE_ACTIONS=1` in the environment the robots are tests/lowering/test_actions.py's, whose one action is a
ROS action served by simulated action servers (`SimActions`): each goal sent is written as `<robot> <order>`.

With `SHARE_TD` (a TD whose security is `basic`) and `SHARE_PASSWORDS` (JSON: robot id -> password) in the
environment, each robot connects as its own broker user (its id), as under the ACL `gen -b events` writes, and
the process's own connection (member record, beats, admitted entries) as the first robot's user: the user of
its top-level settings (test_fleet_share_acl.py).

With `SHARE_ROBOTS_FILE` (robot ids, separated by white space) the robots are that file's instead of ROBOTS's
count, and SIGHUP reads it again (as `run` reads its fleet file again). `SHARE_SETTLE` (seconds) is how long the
process waits at its start before it takes its share (a process slow to take what is handed over to it), and
`SHARE_GROW_DELAY` how long each robot's ROS side takes to come up (a slow ROS graph: its claim takes that long);
the log says `starting <robots>` as it begins. With `SHARE_SLOW` (robot ids) only a set of robots with one of those
takes that long, the others come up at once. With `SHARE_CLOSE_DELAY` (seconds) the port of each robot of
`SHARE_SLOW_CLOSE` (robot ids) takes that long to close when the robot leaves (a slow ROS teardown).

With `SHARE_FOUND_FILE` (robot ids) the process also discovers robots (graphwatch.py's `Discovery`), its "graph" that
file, read at each look: a test lists a robot there as a ROS graph would show it; `SHARE_GRAPH` names that graph
(graphwatch.py `Graph.name`), and `SHARE_LOOK_DELAY` is how long each look takes. The process then prints
`planned` once its share made its first plan (what is listed before is given out at once). `SHARE_NEW_SETTLE` sets
share.SETTLE, how long a newly listed robot waits for the members that list it a moment later.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from td2adaptor.runtime.config import RuntimeConfig, load_defaults, robot_config
from td2adaptor.runtime.node import share as shared
from td2adaptor.runtime.node.fleet import Fleet
from td2adaptor.runtime.node.graphwatch import Discovery, Signature
from td2adaptor.runtime.node.roslink import RosLink
from td2adaptor.runtime.node.share import Share, share_bus
from td2adaptor.runtime.ros.port import GoalListener, StartResult
from td2adaptor.runtime.ros.simport import SimActions, SimPort
from tests.runtime.rb1 import compile_td, rb1_model, sim

FLEET = "shared"


class FileGraph:
    """A "ROS graph" that shows the robots a file names (each its own namespace), read again at each look."""

    def __init__(self, path: Path, name: str = "", delay: float = 0.0) -> None:
        self.path = path
        self.name = name  # "": unknown, every process may see what another finds
        self.delay = delay  # seconds each look takes (a slow graph)

    def robots(self, sig: Signature, known: set[str]) -> set[str]:
        time.sleep(self.delay)
        try:
            return set(self.path.read_text().split())
        except FileNotFoundError:
            return set()


class LoggedPort(SimPort):
    """A simulated robot that writes down each mission it starts (one line, one write: O_APPEND keeps lines
    of several processes whole)."""

    runs_fd = -1

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> StartResult:
        result = super().start(component, action, payload, timeout)
        goals = payload.get("procedure", {}).get("goals", [{}])
        x = goals[0].get("pose", {}).get("x") if goals else None
        os.write(self.runs_fd, f"{self.robot} {x} {os.getpid()}\n".encode())
        return result

    def start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str:
        goal = super().start_goal(component, action, payload, timeout, listener)
        os.write(self.runs_fd, f"{self.robot} {payload.get('order')} {os.getpid()}\n".encode())
        return goal

    robot = ""
    close_delay = 0.0

    def close(self) -> None:
        time.sleep(self.close_delay)


def main() -> None:
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("td2adaptor.runtime.share").setLevel(logging.INFO)
    logging.getLogger("td2adaptor.runtime.fleet").setLevel(logging.INFO)  # where each robot that joins came from
    url, state_dir, count, runs = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    if sys.argv[5:] == ["own"]:  # another host: no state directory shared with the others
        state_dir = os.path.join(state_dir, str(os.getpid()))
    LoggedPort.runs_fd = os.open(runs, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
    settings = {"bus": url, "poll_period": 0.05, "property_period": 0, "presence_period": 0, "state_dir": state_dir}
    robots = [f"rb_{i:02d}" for i in range(count)]
    listed = os.environ.get("SHARE_ROBOTS_FILE")
    if listed:
        robots = Path(listed).read_text().split()
    passwords: dict[str, str] = json.loads(os.environ.get("SHARE_PASSWORDS", "{}"))
    model = compile_td(Path(os.environ["SHARE_TD"])) if "SHARE_TD" in os.environ else rb1_model()
    actions = None
    if os.environ.get("SHARE_ACTIONS"):
        from tests.runtime.threads_proc import action_model

        model, actions = action_model(), SimActions(step=0.05)
    if passwords:  # the top-level settings' user: the first robot's
        settings |= {"username": robots[0], "password": passwords[robots[0]]}
    defaults = load_defaults(env={}, overrides={**settings, "fleet": FLEET})
    candidates = [robot_config(defaults, robot) for robot in robots]
    if passwords:  # each robot its own user
        candidates = [replace(c, username=c.robot, password=passwords[c.robot]) for c in candidates]

    delay = float(os.environ.get("SHARE_GROW_DELAY", "0"))
    slow = set(os.environ.get("SHARE_SLOW", "").split())
    slow_close = set(os.environ.get("SHARE_SLOW_CLOSE", "").split())
    close_delay = float(os.environ.get("SHARE_CLOSE_DELAY", "0"))

    def grow(configs: Sequence[RuntimeConfig]) -> RosLink:
        logging.getLogger("td2adaptor.runtime.share").info("starting %s", " ".join(c.robot for c in configs))
        if not slow or slow & {c.robot for c in configs}:
            time.sleep(delay)
        ports = {}
        for c in configs:
            port = LoggedPort(model, sim(0.3))
            if actions is not None:  # no properties there, one ROS action
                port = LoggedPort(model, sim(0.3), readers={}, writers={}, actions=actions)
            port.robot = c.robot
            port.close_delay = close_delay if c.robot in slow_close else 0.0
            ports[c.robot] = port
        return RosLink(ports=dict(ports))

    fleet = Fleet(model, RosLink(grow=grow), distro="ros2")
    template = robot_config(defaults, "stand-in")
    keepalive = int(os.environ.get("SHARE_KEEPALIVE", template.share_keepalive))
    bus = share_bus(template, model, name=FLEET, keepalive=keepalive)
    settle = float(os.environ.get("SHARE_SETTLE", "1"))
    share = Share(
        fleet,
        bus,
        name=FLEET,
        root="td2adaptor",
        timeout=template.share_timeout,
        settle=settle,
        make_config=lambda robot, namespace: robot_config(defaults, robot, namespace),  # as `run` gives it
    )
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    reloading = threading.Lock()

    def reload() -> None:  # as FleetFile does: off the signal handler
        with reloading:
            wanted = Path(listed or "").read_text().split()
            changes = share.apply([robot_config(defaults, robot) for robot in wanted])
            logging.getLogger("td2adaptor.runtime.share").info("reloaded: %s: %s", " ".join(wanted), changes.describe())

    if listed:
        signal.signal(signal.SIGHUP, lambda *_: threading.Thread(target=reload, daemon=True).start())
    if "SHARE_NEW_SETTLE" in os.environ:
        shared.SETTLE = float(os.environ["SHARE_NEW_SETTLE"])
    share.start(candidates)
    found = os.environ.get("SHARE_FOUND_FILE")
    discovery = None
    if found:
        sig = Signature(("x",), (), ())
        make = lambda robot, namespace: robot_config(defaults, robot, namespace)  # noqa: E731
        graph = FileGraph(
            Path(found), os.environ.get("SHARE_GRAPH", ""), float(os.environ.get("SHARE_LOOK_DELAY", "0"))
        )
        discovery = Discovery(share, graph, sig, make, grace=1.0)
        share.follow(discovery)
        discovery.start()
    print("ready", share.me.node, flush=True)
    if found:
        while not share._planned and not done.wait(0.01):
            pass
        print("planned", flush=True)
    done.wait()
    if discovery is not None:
        discovery.stop()
    share.stop()
    fleet.stop()


if __name__ == "__main__":
    main()
