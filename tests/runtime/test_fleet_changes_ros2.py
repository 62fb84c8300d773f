"""Robots join and leave a running `td2adaptor run` (issue 32), for real: the edge node in a process of its own,
the simulated RB-1s in theirs (ROS 2 Jazzy), a real mosquitto. The fleet file changed on disk and reloaded on
SIGHUP (under load: the other robots' missions go on untouched), a file that became invalid (the fleet is kept),
discovery of a robot that appears and disappears in the ROS graph, and admin requests on the bus (signed, and
refused when unsigned or when the fleet has no admin).
"""

from __future__ import annotations

import json
import re
import signal
import sys
import threading
import time
from collections.abc import Iterator
from functools import partial
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime.events import now_rfc3339
from tests.ros2 import env
from tests.ros2.common import EXAMPLE, PACKAGE, Process
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import RunProcess, check_mission, feedback, stretched, until
from tests.runtime.rb1 import GOAL, terminal

pytest_plugins = ["tests.ros2.fixtures"]  # ros2_domain, rb1_prefix, adaptor_build

#: the namespaces of this module's simulated robots (no other ROS 2 test uses them)
NAMESPACES = tuple(f"fc_{x}" for x in "abcde")
DURATION = 2.0  # how long a mission runs on the simulated robot
SERVED_WITHIN = 2.0  # seconds from the change to the robot's `online` status (issue 32)
ADMIN_KEY = "k3y-of-the-fleet-admin-for-tests"


def goto(robot: str) -> str:
    return f"td2adaptor/{robot}/GoToComponent/gotoRun"


def sim_process(prefix: Path, namespaces: tuple[str, ...], domain: int | None = None) -> Process:
    """The simulated RB-1s of `namespaces` in a process of their own (on ROS domain `domain`, else this worker's)."""
    # not --quiet: the robots' `call` events say, when a mission fails, whether its call reached the robot
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", str(DURATION)]
    for ns in namespaces:
        args += ["--namespace", ns]
    environ = env.child_env([prefix])
    if domain is not None:
        environ["ROS_DOMAIN_ID"] = str(domain)
    process = Process(args, environ)
    try:
        process.wait_for(lambda e: e.get("event") == "ready", timeout=60)
    except BaseException:
        process.stop()
        raise
    return process


@pytest.fixture(scope="module")
def robots(rb1_prefix: Path) -> Iterator[Process]:
    process = sim_process(rb1_prefix, NAMESPACES)
    yield process
    process.stop()


class Watch:
    """An application that records everything under td2adaptor/#, with the time each event came."""

    def __init__(self, broker: Mosquitto, name: str) -> None:
        self.app = AppClient(broker.url, ["td2adaptor/#"], client_id=name)
        self.came: list[float] = []
        self.answered: set[str] = set()  # robots that answered a query through the edge node (`answering`)
        on_message = self.app.client.on_message

        def stamped(*args: Any) -> None:
            on_message(*args)
            self.came.append(time.monotonic())

        self.app.client.on_message = stamped

    def statuses(self, robot: str) -> list[str]:
        """The robot's states, one per change: a status that says the state again is no new one (the status
        also carries the robot's presence, missions and last error, issue 32), unless it is a status published
        again (the same event: what a reconnection publishes), which counts."""
        out: list[str] = []
        seen: set[str] = set()
        for t, e in self.app.events:
            if t != f"td2adaptor/{robot}/status":
                continue
            state, again = e["payload"]["state"], e.get("id") in seen
            seen.add(e.get("id"))
            if again or out[-1:] != [state]:
                out.append(state)
        return out

    def status_at(self, robot: str, state: str, after: float) -> float | None:
        """When the first `state` status of `robot` came after `after`."""
        for (t, e), when in zip(list(self.app.events), list(self.came), strict=False):
            if t == f"td2adaptor/{robot}/status" and e["payload"]["state"] == state and when >= after:
                return when
        return None

    def tds(self, robot: str) -> list[dict[str, Any]]:
        return [e for t, e in self.app.events if t == f"td2adaptor/{robot}/td"]

    def wait_status(self, robot: str, state: str, timeout: float = 30.0) -> None:
        self.app.wait(lambda _ev: self.statuses(robot)[-1:] == [state], timeout=timeout)

    def close(self) -> None:
        self.app.close()


def fleet_file(path: Path, broker: Mosquitto, robots: dict[str, str], **extra: Any) -> None:
    lines = [f"bus: {broker.url}", "poll_period: 0.1", "property_period: 0", "call_timeout: 5", 'state_dir: ""']
    lines += [f"{k}: {v}" for k, v in extra.items()]
    lines += ["robots:", *(f"  - {{robot: {r}, namespace: {ns}}}" for r, ns in robots.items())]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def run_args(*more: str) -> list[str]:
    return [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--package", PACKAGE, *more]


def node_env(rb1_prefix: Path, adaptor_build: tuple[Path, Path], **extra: str) -> dict[str, str]:
    environ = env.child_env([rb1_prefix, adaptor_build[1]])
    environ.update(extra)
    return environ


def answered_to(correlation: str, events: list[tuple[str, dict[str, Any]]]) -> bool:
    return any(e.get("correlation") == correlation for _, e in events)


def answering(watch: Watch, robot: str, timeout: float = 30.0) -> None:
    """Wait until `robot` answers a (side-effect free) query through the edge node. A ROS 2 service can be
    discovered before its server has discovered the client's response reader: the first request's answer is
    then lost (tests/runtime/test_edge_node_ros2.py's `answers`), and the mission started by that request
    fails `unreachable` (seen once on CI's loaded machine): a new edge node's first mission waits for this."""
    deadline = time.monotonic() + timeout
    attempt = 0
    while time.monotonic() < deadline:
        attempt += 1
        correlation = f"answering-{robot}-{attempt}"
        watch.app.send(f"td2adaptor/{robot}/GoToComponent/gotoQuery", {"correlation": correlation})
        try:
            events = watch.app.wait(partial(answered_to, correlation), 10)
        except AssertionError:
            continue
        answer = [e for _, e in events if e.get("correlation") == correlation]
        if "unreachable" not in json.dumps(answer) and "did not answer" not in json.dumps(answer):
            watch.answered.add(robot)
            return
    raise AssertionError(f"{robot} never answered a query in {timeout:g} s")


def mission(watch: Watch, robot: str, correlation: str) -> None:
    if robot not in watch.answered:
        answering(watch, robot)
    watch.app.send(goto(robot), {"correlation": correlation, "payload": GOAL})


def check(watch: Watch, correlation: str, run: RunProcess, robots: Process | None) -> None:
    """`check_mission` for a mission that finished; when it did not, the message says what the edge node logged
    and what the simulated robots saw (their `call` events, their stderr): whether the call reached a robot."""
    try:
        check_mission(watch.app.events, correlation, ["queued", "running", "finished"])
    except AssertionError as failure:
        said = f"{failure}\nedge node: {run.output()[-3000:]}"
        if robots is not None:
            calls = [e for e in robots.drain() if e.get("event") == "call"]
            said += f"\nrobots' last calls: {calls[-12:]}\nrobots' stderr: {robots.stderr_tail()}"
        raise AssertionError(said) from None


def test_robots_added_to_and_removed_from_the_fleet_file_join_and_leave_without_touching_the_others(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.yaml"
    fleet_file(fleet, broker, {"keep": "fc_a", "leave": "fc_b"})
    watch = Watch(broker, "fleet-file-app")
    run = RunProcess(run_args("--config", str(fleet)), env=node_env(rb1_prefix, adaptor_build))
    try:
        run.wait_ready()
        watch.wait_status("keep", "online")
        watch.wait_status("leave", "online")
        mission(watch, "keep", "kept-1")
        mission(watch, "leave", "cut-1")
        watch.app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, "cut-1")], timeout=20)
        watch.app.wait(lambda ev: "running" in [e["payload"]["state"] for e in feedback(ev, "kept-1")], timeout=20)

        changed = time.monotonic()  # the file changes on disk: no signal
        fleet_file(fleet, broker, {"keep": "fc_a", "joined": "fc_c"})
        watch.wait_status("joined", "online", timeout=30)
        took = (watch.status_at("joined", "online", changed) or 1e9) - changed
        # the node looks every half second and waits for the file to stand still one look
        print(f"file change -> online: {took:.2f} s")
        assert took <= stretched(SERVED_WITHIN), f"served {took:.2f} s after the change"
        watch.wait_status("leave", "offline", timeout=30)
        # the removed robot's mission in flight ended with one clear terminal event
        watch.app.wait(terminal("feedback", "cut-1"), timeout=20)
        last = feedback(watch.app.events, "cut-1")[-1]["payload"]
        assert (last["state"], last["reason"], last["terminal"]) == ("failed", "unreachable", True), last
        assert "removed from the edge node's fleet" in last["message"], last
        assert watch.tds("leave")[-1] == {"raw": ""}  # its retained TD cleared

        # the robot that stayed: one online status, no reconnection, its mission undisturbed
        watch.app.wait(terminal("feedback", "kept-1"), timeout=20)
        check(watch, "kept-1", run, robots)
        assert watch.statuses("keep") == ["online"]
        # the robot that joined serves missions
        mission(watch, "joined", "new-1")
        watch.app.wait(terminal("feedback", "new-1"), timeout=30)
        check(watch, "new-1", run, robots)
        assert "reloaded (it changed on disk): added joined; removed leave" in run.output()
        assert run.proc.poll() is None
    finally:
        code = run.terminate(signal.SIGTERM)
        watch.close()
    assert code == 0, run.output()


def test_sighup_reloads_the_fleet_under_load_and_the_other_robots_missions_go_on(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.yaml"
    fleet_file(fleet, broker, {"busy_a": "fc_a", "busy_b": "fc_b", "changed": "fc_c"})
    watch = Watch(broker, "sighup-app")
    run = RunProcess(run_args("--config", str(fleet)), env=node_env(rb1_prefix, adaptor_build))
    stop = threading.Event()
    sent: dict[str, list[str]] = {"busy_a": [], "busy_b": []}

    def load(robot: str) -> None:  # one mission after the other, all the time
        n = 0
        while not stop.is_set():
            n += 1
            correlation = f"{robot}-{n}"
            sent[robot].append(correlation)
            mission(watch, robot, correlation)
            watch.app.wait(terminal("feedback", correlation), timeout=30)

    try:
        run.wait_ready()
        for robot in ("busy_a", "busy_b", "changed"):
            watch.wait_status(robot, "online")
        loaders = [threading.Thread(target=load, args=(r,)) for r in sent]
        for thread in loaders:
            thread.start()
        assert until(lambda: all(len(v) >= 2 for v in sent.values()), 30)
        # one robot's settings change, one joins; the signal comes at once, before the node's look at the file
        # could take the change (it waits until the file stood still for one look)
        fleet_file(fleet, broker, {"busy_a": "fc_a", "busy_b": "fc_b", "changed": "fc_d", "added": "fc_e"})
        hup = time.monotonic()
        run.proc.send_signal(signal.SIGHUP)
        watch.wait_status("added", "online", timeout=30)
        took = (watch.status_at("added", "online", hup) or 1e9) - hup
        print(f"SIGHUP -> online: {took:.2f} s")
        assert took <= stretched(SERVED_WITHIN), f"served {took:.2f} s after SIGHUP"
        assert until(lambda: watch.status_at("changed", "online", hup) is not None, 30)
        assert until(lambda: all(len(v) >= 5 for v in sent.values()), 60)
        stop.set()
        for thread in loaders:
            thread.join(60)
        for robot, correlations in sent.items():
            for correlation in correlations:
                check(watch, correlation, run, robots)
            assert watch.statuses(robot) == ["online"], robot  # never offline, never reconnected
        # the changed robot restarted alone, on its new namespace
        assert watch.statuses("changed") == ["online", "offline", "online"]
        mission(watch, "added", "added-1")
        watch.app.wait(terminal("feedback", "added-1"), timeout=30)
        check(watch, "added-1", run, robots)
        assert "reloaded (SIGHUP): added added; restarted changed" in run.output()
    finally:
        stop.set()
        code = run.terminate(signal.SIGTERM)
        watch.close()
    assert code == 0, run.output()


def test_a_fleet_file_that_became_invalid_is_reported_and_the_fleet_is_kept(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.yaml"
    fleet_file(fleet, broker, {"stay_a": "fc_a", "stay_b": "fc_b"})
    watch = Watch(broker, "invalid-app")
    run = RunProcess(run_args("--config", str(fleet)), env=node_env(rb1_prefix, adaptor_build))
    try:
        run.wait_ready()
        watch.wait_status("stay_a", "online")
        watch.wait_status("stay_b", "online")
        text = fleet.read_text(encoding="utf-8")
        fleet.write_text(text.replace("robots:", "robots:\n  - {robot: stay_a, namespace: fc_c}"), encoding="utf-8")
        run.proc.send_signal(signal.SIGHUP)
        assert until(lambda: "not reloaded (SIGHUP)" in run.output(), 20), run.output()
        assert "robot ids must be unique" in run.output()
        fleet.write_text(text + "bogus_key: 1\n", encoding="utf-8")  # the same on disk, no signal
        assert until(lambda: "unknown key 'bogus_key'" in run.output(), 20), run.output()
        assert "the running fleet is kept as it is" in run.output()
        assert "Traceback" not in run.output()
        mission(watch, "stay_a", "still-1")
        watch.app.wait(terminal("feedback", "still-1"), timeout=30)
        check(watch, "still-1", run, robots)
        assert watch.statuses("stay_a") == ["online"] and watch.statuses("stay_b") == ["online"]
        fleet_file(fleet, broker, {"stay_a": "fc_a"})  # valid again: taken
        watch.wait_status("stay_b", "offline", timeout=30)
        assert run.proc.poll() is None
    finally:
        code = run.terminate(signal.SIGTERM)
        watch.close()
    assert code == 0, run.output()


def test_discovery_serves_a_robot_that_appears_in_the_ros_graph_and_retires_it_when_it_is_gone(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, broker: Mosquitto, tmp_path: Path
) -> None:
    settings = tmp_path / "defaults.yaml"
    settings.write_text(f"bus: {broker.url}\npoll_period: 0.1\nproperty_period: 0\nstate_dir: ''\n", encoding="utf-8")
    watch = Watch(broker, "discovery-app")
    args = run_args("--config", str(settings), "--discover", "--discover-grace", "1")
    # a ROS domain of its own: this worker's module-scoped `robots` (fc_a..fc_e), started by an earlier test of
    # this module or not depending on the order xdist gives, must not be discovered too
    domain = str(env.private_domain_id())
    run = RunProcess(args, env=node_env(rb1_prefix, adaptor_build, ROS_DOMAIN_ID=domain))
    robot: Process | None = None
    try:
        run.wait_ready()
        assert "serving no robot yet" in run.output()
        # a file of settings only that no longer reads is refused as a fleet file is (it was "reloaded: no
        # change", a new user's lift fleet with `poll_period: -1`), and discovery goes on
        good = settings.read_text(encoding="utf-8")
        settings.write_text(good.replace("poll_period: 0.1", "poll_period: -1"), encoding="utf-8")
        run.proc.send_signal(signal.SIGHUP)
        assert until(lambda: "not reloaded (SIGHUP)" in run.output(), 20), run.output()
        assert "poll_period must be positive" in run.output() and "reloaded (SIGHUP): no change" not in run.output()
        settings.write_text(good, encoding="utf-8")
        robot = sim_process(rb1_prefix, ("disc_a",), domain=int(domain))
        appeared = time.monotonic()  # the simulated robot said it is ready
        watch.wait_status("disc_a", "online", timeout=30)
        took = (watch.status_at("disc_a", "online", appeared) or 1e9) - appeared
        print(f"appeared -> online: {took:.2f} s")
        assert took <= stretched(SERVED_WITHIN), f"served {took:.2f} s after it appeared"
        td = watch.tds("disc_a")[-1]
        assert td["id"].endswith(":disc_a"), td["id"]
        mission(watch, "disc_a", "found-1")
        watch.app.wait(terminal("feedback", "found-1"), timeout=30)
        check(watch, "found-1", run, robot)

        gone = time.monotonic()
        robot.stop()  # its nodes leave the ROS graph (a robot killed leaves it when DDS's lease runs out)
        watch.wait_status("disc_a", "offline", timeout=30)
        assert watch.tds("disc_a")[-1] == {"raw": ""}
        retired = (watch.status_at("disc_a", "offline", gone) or 1e9) - gone
        # the grace period of 1 s runs from the first look that missed it (tests/runtime/test_discovery_grace.py);
        # on a loaded machine a look may miss a robot that is still there (its endpoints not all in the graph),
        # which starts it early if no later look sees the robot again; retired at once would mean no grace at all
        assert retired >= 0.25, retired
        removed = re.compile(r"discovery: [^\n]*removed [^\n]*\bdisc_a\b")
        assert until(lambda: removed.search(run.output()) is not None, 10), run.output()
        assert re.search(r"discovery: added disc_a\b", run.output()), run.output()

        # no admin configured: an admin request is answered, and refused
        from td2adaptor.runtime.node.admin import admin_topics, sign

        request, answer = admin_topics("td2adaptor", PACKAGE)
        body = {"id": "adm-0", "time": now_rfc3339(), "op": "add", "robot": "x1", "namespace": "fc_a"}
        watch.app.send(request, sign(body, ADMIN_KEY))
        watch.app.wait(lambda ev: any(t == answer for t, _ in ev), timeout=20)
        got = next(e for t, e in watch.app.events if t == answer)
        assert got["correlation"] == "adm-0" and got["payload"]["code"] == "refused", got
        assert watch.statuses("x1") == []
    finally:
        if robot is not None:
            robot.stop()
        code = run.terminate(signal.SIGTERM)
        watch.close()
    assert code == 0, run.output()


def test_admin_requests_add_and_remove_a_robot_and_an_unauthorised_one_is_refused(
    adaptor_build: tuple[Path, Path], rb1_prefix: Path, robots: Process, broker: Mosquitto, tmp_path: Path
) -> None:
    fleet = tmp_path / "fleet.yaml"
    from td2adaptor.runtime.node.admin import admin_topics, sign

    fleet_file(fleet, broker, {"first": "fc_a"}, fleet="site_7")
    watch = Watch(broker, "admin-app")
    environ = node_env(rb1_prefix, adaptor_build, TD2ADAPTOR_FLEET_ADMIN_KEY=ADMIN_KEY)
    run = RunProcess(run_args("--config", str(fleet)), env=environ)
    request, answer = admin_topics("td2adaptor", "site_7")

    def ask(body: dict[str, Any], key: str | None = ADMIN_KEY) -> dict[str, Any]:
        body = {"id": f"adm-{time.monotonic_ns()}", "time": now_rfc3339(), **body}
        watch.app.send(request, sign(body, key) if key else body)
        watch.app.wait(lambda ev: any(t == answer and e.get("correlation") == body["id"] for t, e in ev), 30)
        return next(e for t, e in watch.app.events if t == answer and e.get("correlation") == body["id"])

    try:
        run.wait_ready()
        watch.wait_status("first", "online")
        sent = time.monotonic()
        added = ask({"op": "add", "robot": "second", "namespace": "fc_b"})
        assert added["payload"] == {
            "ok": True,
            "code": "added",
            "op": "add",
            "robot": "second",
            "message": "robot second is served (namespace fc_b)",
        }
        watch.wait_status("second", "online")
        took = (watch.status_at("second", "online", sent) or 1e9) - sent
        print(f"admin add -> online: {took:.2f} s")
        assert took <= stretched(SERVED_WITHIN), took
        mission(watch, "second", "adm-m1")
        watch.app.wait(terminal("feedback", "adm-m1"), timeout=30)
        check(watch, "adm-m1", run, robots)

        # a stranger: unsigned, signed with another key, a replay of a signed one
        assert ask({"op": "remove", "robot": "first"}, key=None)["payload"]["code"] == "unauthorised"
        wrong = ask({"op": "remove", "robot": "first"}, key="not-the-fleet-admin-key-at-all")
        assert wrong["payload"]["code"] == "unauthorised" and not wrong["payload"]["ok"]
        body = sign(
            {"id": "once", "time": now_rfc3339(), "op": "add", "robot": "third", "namespace": "fc_c"}, ADMIN_KEY
        )
        watch.app.send(request, body)
        watch.app.send(request, body)
        watch.app.wait(lambda ev: len([1 for t, e in ev if t == answer and e.get("correlation") == "once"]) == 2, 30)
        codes = [e["payload"]["code"] for t, e in watch.app.events if t == answer and e.get("correlation") == "once"]
        assert codes == ["added", "replayed"], codes
        assert watch.statuses("first") == ["online"]

        removed = ask({"op": "remove", "robot": "second"})
        assert removed["payload"]["code"] == "removed", removed
        watch.wait_status("second", "offline")
        assert watch.tds("second")[-1] == {"raw": ""}
        assert ask({"op": "remove", "robot": "second"})["payload"]["code"] == "not-served"
        assert ask({"op": "add", "robot": "first", "namespace": "fc_a"})["payload"]["code"] == "served-already"
        assert watch.statuses("first") == ["online"]
        assert ADMIN_KEY not in run.output()
    finally:
        code = run.terminate(signal.SIGTERM)
        watch.close()
    assert code == 0, run.output()
