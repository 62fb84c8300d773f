"""A robot's status tells the truth (issue 32): its edge node online or offline, its ROS side present or absent,
the process that owns it; one owner per robot; the operator's `fleet status`; the Prometheus metrics. On a real
mosquitto, with the simulated RB-1 (its `down` switch watched as the robot's presence). The same on real ROS 2
with `td2adaptor run` processes: test_presence_ros2.py."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime import Engine, RuntimeConfig, serve
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.node.claims import check_fleet
from td2adaptor.runtime.node.owner import OwnerConflict, this_process
from td2adaptor.runtime.ros.simport import SimPort
from tests.conftest import REPO
from tests.ports import free_port
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import bus_of, until
from tests.runtime.rb1 import GOAL, check_outbound, rb1_model, sim, terminal

ROBOT = "pres_a"
GOTO = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"


def config(broker: Mosquitto, **kw: Any) -> RuntimeConfig:
    base: dict[str, Any] = {
        "robot": ROBOT,
        "bus": broker.url,
        "poll_period": 0.05,
        "property_period": 0,
        "call_timeout": 10.0,
        "presence_period": 0.1,
        "state_dir": "",
    }
    return RuntimeConfig(**{**base, **kw})


def statuses(events: list[tuple[str, dict[str, Any]]], robot: str = ROBOT) -> list[dict[str, Any]]:
    return [e["payload"] for t, e in events if t == f"td2adaptor/{robot}/status" and "payload" in e]


def last_status(robot: str = ROBOT) -> Any:
    return lambda ev: statuses(ev, robot)[-1:]


def test_the_status_says_whether_the_robot_is_there_and_an_invoke_to_an_absent_robot_is_answered_at_once(
    broker: Mosquitto,
) -> None:
    model = rb1_model()
    port = SimPort(model, sim(0.3))
    port.watched = True  # the test's switch: `down` is the robot's ROS side gone
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
    engine = serve(model, port, config(broker))
    try:
        app.wait(lambda ev: any(s.get("robot") == "present" for s in statuses(ev)))
        (online,) = [s for s in statuses(app.events) if s.get("robot") == "present"][:1]
        me = this_process()
        assert online["state"] == "online" and online["owner"] == me.to_json() and online["missions"] == 0
        assert online["owner"]["pid"] == os.getpid()
        port.down = True  # the robot's ROS nodes are gone
        went = time.monotonic()
        app.wait(lambda ev: statuses(ev)[-1].get("robot") == "absent", timeout=5)
        assert time.monotonic() - went < 2.0  # within a few presence periods
        absent = statuses(app.events)[-1]
        assert absent["state"] == "online" and "gotoRun" in absent["missing"]
        calls = len(port.calls)
        sent = time.monotonic()
        app.send(GOTO, {"correlation": "gone", "payload": GOAL})
        app.wait(terminal("feedback", "gone"), timeout=5)
        assert time.monotonic() - sent < 2.0  # at once: not after call_timeout (10 s)
        (error,) = [e for _, e in app.events if e.get("type") == "error" and e.get("correlation") == "gone"]
        assert error["payload"]["code"] == "absent" and "gotoRun" in error["payload"]["message"]
        (end,) = [e for _, e in app.events if e.get("type") == "feedback" and e.get("correlation") == "gone"]
        assert (end["payload"]["state"], end["payload"]["reason"], end["payload"]["terminal"]) == (
            "failed",
            "unreachable",
            True,
        )
        assert len(port.calls) == calls  # never sent to the robot
        # the last error is in the status (what `fleet status` shows)
        app.wait(lambda ev: (statuses(ev)[-1].get("lastError") or {}).get("code") == "absent")
        port.down = False  # back
        app.wait(lambda ev: statuses(ev)[-1].get("robot") == "present", timeout=5)
        app.send(GOTO, {"correlation": "back", "payload": GOAL})
        app.wait(terminal("feedback", "back"), timeout=10)
        assert [e for _, e in app.events if e.get("correlation") == "back"][-1]["payload"]["state"] == "finished"
    finally:
        engine.stop()
    app.wait(lambda ev: statuses(ev)[-1]["state"] == "offline")
    assert statuses(app.events)[-1]["owner"] == this_process().to_json()  # who served it last
    app.close()
    check_outbound(app.events)


def test_a_robot_not_discovered_yet_at_start_is_not_said_absent_until_the_grace_ends(broker: Mosquitto) -> None:
    """At start-up the ROS graph takes a second or two to show the robot's servers (DDS discovery), and an invoke
    meanwhile waits for its server (nothing is refused before `call_timeout`). The status said `absent` all the
    same, on every start of a node whose robot was there (a new user's conveyor fleet; so did the directory and
    the metrics). Now the status has no `robot` member until a server is seen or the grace ends; a robot still
    missing then is `absent`, and the hooks (the directory) learn that change of time too."""
    model = rb1_model()
    grace = 1.5
    for robot, comes in (("pres_late", True), ("pres_never", False)):
        port = SimPort(model, sim(0.05))
        port.watched, port.down = True, True  # not discovered yet
        app = AppClient(broker, [f"td2adaptor/{robot}/#"])
        engine = serve(model, port, config(broker, robot=robot, call_timeout=grace))
        started = time.monotonic()
        try:
            app.wait(lambda ev: bool(statuses(ev, robot)), timeout=5)  # noqa: B023 - waited for here
            time.sleep(0.5)  # a few looks that find nothing
            assert [s.get("robot") for s in statuses(app.events, robot)] == [None] * len(statuses(app.events, robot))
            if comes:
                port.down = False
                app.wait(lambda ev: statuses(ev, robot)[-1].get("robot") == "present", timeout=5)  # noqa: B023
                words = {s.get("robot") for s in statuses(app.events, robot)}
                assert words == {None, "present"}, words  # never absent
            else:
                app.wait(lambda ev: statuses(ev, robot)[-1].get("robot") == "absent", timeout=grace + 5)  # noqa: B023
                assert time.monotonic() - started >= grace  # not before the grace ended
                assert "gotoRun" in statuses(app.events, robot)[-1]["missing"]
        finally:
            engine.stop()
            app.close()


def test_a_robot_missing_at_start_is_said_absent_once_discovery_settles_not_after_call_timeout(
    broker: Mosquitto,
) -> None:
    """A node restarted with no robot there: its status had no `robot` member for `call_timeout` (10 s), until
    the grace of the refusals ended (a new user's dock charger). Now the word waits for discovery only
    (`DISCOVERY_SETTLE`, 2 s); the invokes still wait for their server until `call_timeout`."""
    from td2adaptor.runtime.node.presence import DISCOVERY_SETTLE

    robot = "pres_gone"
    port = SimPort(rb1_model(), sim(0.05))
    port.watched, port.down = True, True  # not there at all
    app = AppClient(broker, [f"td2adaptor/{robot}/#"])
    engine = serve(rb1_model(), port, config(broker, robot=robot, call_timeout=10.0))
    started = time.monotonic()
    try:
        app.wait(lambda ev: statuses(ev, robot)[-1:] and statuses(ev, robot)[-1].get("robot") == "absent", timeout=8)
        took = time.monotonic() - started
        assert DISCOVERY_SETTLE - 0.2 <= took < DISCOVERY_SETTLE + 3.0, took  # not before it, nor 10 s later
        assert "gotoRun" in statuses(app.events, robot)[-1]["missing"]
    finally:
        engine.stop()
        app.close()


def test_a_second_owner_of_a_robot_is_refused_and_a_stale_record_is_not(broker: Mosquitto) -> None:
    model = rb1_model()
    engine = serve(model, SimPort(model, sim(0.3)), config(broker))
    try:
        app = AppClient(broker, [f"td2adaptor/{ROBOT}/status"])
        app.wait(lambda ev: bool(statuses(ev)))
        with pytest.raises(OwnerConflict, match=rf"robot {ROBOT} is already served by process {os.getpid()} on "):
            check_fleet(model, [config(broker)])
        assert bus_of(engine).connected  # the first is untouched
        app.close()
    finally:
        engine.stop()
    check_fleet(model, [config(broker)])  # stopped: offline, free
    # a record of this host whose process is gone (killed before the broker noticed): stale, not an owner
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    record = {**this_process().to_json(), "pid": dead.pid, "node": "0" * 16}
    stale = {"type": "status", "robot": "pres_b", "payload": {"state": "online", "owner": record}}
    writer = AppClient(broker, ["td2adaptor/pres_b/status"])
    writer.client.publish("td2adaptor/pres_b/status", json.dumps(stale), qos=1, retain=True).wait_for_publish(5)
    writer.close()
    check_fleet(model, [config(broker, robot="pres_b")])


def test_a_second_node_that_takes_the_session_over_stops_the_first_instead_of_flapping(broker: Mosquitto) -> None:
    """Two nodes started at the same moment both find the robot free; the broker gives the session to the later
    one (MQTT 5 'Session taken over'), and the earlier one stops instead of taking it back."""
    model = rb1_model()
    first = serve(model, SimPort(model, sim(0.3)), config(broker))
    halted: list[str] = []
    first.on_halt.append(halted.append)
    second: Engine | None = None
    try:
        second = serve(model, SimPort(model, sim(0.3)), config(broker))
        assert until(lambda: bool(halted), 5.0), "the first node went on"
        assert "took its session over" in halted[0] and "served by process" in halted[0] and first.failure == halted[0]
        raw = bus_of(second)
        assert isinstance(raw, MqttBus)
        # the first asks whose the robot is before it reconnects (mqttbus.py `_may_reconnect`): it never takes the
        # session back, so the second keeps its one connection
        assert until(lambda: raw.connected, 10.0)
        time.sleep(5.0)  # a window for a few reconnections (1-4 s back-off), were either taking the session back
        assert raw.connected and raw.connects == 1
        app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
        app.send(GOTO, {"correlation": "second", "payload": GOAL})
        app.wait(terminal("feedback", "second"))
        app.close()
    finally:
        first.stop()
        if second is not None:
            second.stop()


def run_cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "td2adaptor", *args],
        cwd=REPO,
        env={**os.environ, **(env or {})},
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_fleet_status_lists_robots_owners_presence_missions_and_the_last_error(broker: Mosquitto) -> None:
    model = rb1_model()
    port = SimPort(model, sim(30.0))
    port.watched = True
    engine = serve(model, port, config(broker))
    other = serve(model, SimPort(model, sim(0.3)), config(broker, robot="pres_c"))
    try:
        app = AppClient(broker, ["td2adaptor/+/status"])
        app.send(GOTO, {"correlation": "long", "payload": GOAL})  # in flight for 30 s
        app.send(f"td2adaptor/{ROBOT}/GoToComponent/gotoQuery", b"not json")  # an error
        app.wait(lambda ev: any(s.get("missions") == 1 and "lastError" in s for s in statuses(ev)))
    finally:
        other.stop()
    try:
        done = run_cli("fleet", "status", "--bus", broker.url)
        assert done.returncode == 0, done.stderr
        lines = done.stdout.splitlines()
        assert lines[0].split() == ["ROBOT", "STATE", "ROBOT", "SIDE", "OWNER", "MISSIONS", "LAST", "ERROR"]
        (a,) = [line for line in lines if line.startswith(ROBOT + " ")]
        me = this_process()
        assert a.split()[:4] == [ROBOT, "online", "present", f"{me.pid}@{me.host}"]
        assert " 1 " in a and "invalid-json: " in a
        (c,) = [line for line in lines if line.startswith("pres_c ")]
        assert c.split()[:4] == ["pres_c", "offline", "-", f"{me.pid}@{me.host}"]  # stopped: who served it last
        rows = json.loads(run_cli("fleet", "status", "--bus", broker.url, "--json").stdout)
        assert [r["robot"] for r in rows] == [ROBOT, "pres_c"] and rows[0]["missions"] == 1
        app.close()
    finally:
        engine.stop()


def test_fleet_status_says_clearly_when_the_broker_is_unreachable_or_wants_credentials(tmp_path: Path) -> None:
    gone = run_cli("fleet", "status", "--bus", f"mqtt://127.0.0.1:{free_port()}")
    assert gone.returncode == 1 and "cannot reach the MQTT broker" in gone.stderr and "Traceback" not in gone.stderr
    locked = Mosquitto(tmp_path / "locked", users={"operator": "S3cr3t-pw"})
    locked.start()
    try:
        refused = run_cli("fleet", "status", "--bus", locked.url)
        assert refused.returncode == 1 and "refused an anonymous client" in refused.stderr, refused.stderr
        wrong = run_cli(
            "fleet",
            "status",
            "--bus",
            locked.url,
            env={"TD2ADAPTOR_MQTT_USERNAME": "operator", "TD2ADAPTOR_MQTT_PASSWORD": "not-the-S3cr3t-pw"},
        )
        assert wrong.returncode == 1 and "refused user 'operator'" in wrong.stderr
        assert "S3cr3t" not in wrong.stderr + wrong.stdout  # never a secret
        # one line each: the connection's own log lines ("... refused the connection: Not authorized", "lost the
        # MQTT broker ... (Protocol error); reconnecting" from a command that then exits) said it again, or wrong
        for failed in (refused, wrong):
            assert failed.stderr.strip().splitlines() == [failed.stderr.strip().splitlines()[-1]], failed.stderr
            assert failed.stderr.startswith("td2adaptor fleet status: "), failed.stderr
        ok = run_cli(
            "fleet",
            "status",
            "--bus",
            locked.url,
            env={"TD2ADAPTOR_MQTT_USERNAME": "operator", "TD2ADAPTOR_MQTT_PASSWORD": "S3cr3t-pw"},
        )
        assert ok.returncode == 0 and "no robot has a status" in ok.stdout
    finally:
        locked.stop()


def test_metrics_are_served_in_the_prometheus_text_format(broker: Mosquitto) -> None:
    from td2adaptor.runtime.node.metrics import serve_metrics

    model = rb1_model()
    port = SimPort(model, sim(0.1))
    port.watched = True
    address = f"127.0.0.1:{free_port()}"
    server = serve_metrics(address)
    engine = serve(model, port, config(broker))
    try:
        app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
        app.wait(lambda ev: any(s.get("robot") == "present" for s in statuses(ev)))
        app.send(GOTO, {"correlation": "m1", "payload": GOAL})
        app.wait(terminal("feedback", "m1"))

        def scrape() -> str:
            with urllib.request.urlopen(f"http://{address}/metrics", timeout=10) as answer:
                assert answer.headers["Content-Type"].startswith("text/plain; version=0.0.4")
                return str(answer.read().decode())

        # the mission's end is counted once its terminal event is out (the application may scrape before)
        ended = f'td2adaptor_mission_duration_seconds_count{{robot="{ROBOT}",state="finished"}}'
        assert until(lambda: ended in scrape(), 10)
        text = scrape()
        app.close()
    finally:
        engine.stop()
        server.shutdown()
        server.server_close()
    values = {line.rsplit(" ", 1)[0]: float(line.rsplit(" ", 1)[1]) for line in text.splitlines() if line[:1] != "#"}
    assert values["td2adaptor_robots_owned"] == 1.0
    assert values[f'td2adaptor_robot_online{{robot="{ROBOT}"}}'] == 1.0
    assert values[f'td2adaptor_robot_present{{robot="{ROBOT}"}}'] == 1.0
    assert values[f'td2adaptor_missions_started_total{{robot="{ROBOT}"}}'] == 1.0
    assert values[f'td2adaptor_missions_in_flight{{robot="{ROBOT}"}}'] == 0.0
    assert values[f'td2adaptor_mission_duration_seconds_count{{robot="{ROBOT}",state="finished"}}'] == 1.0
    assert values[f'td2adaptor_mission_duration_seconds_bucket{{le="+Inf",robot="{ROBOT}",state="finished"}}'] == 1.0
    assert values[f'td2adaptor_mqtt_reconnects_total{{robot="{ROBOT}"}}'] == 0.0
    assert "# TYPE td2adaptor_mission_duration_seconds histogram" in text


def test_the_offline_status_of_a_stop_is_stamped_when_the_node_stopped_not_when_it_started(broker: Mosquitto) -> None:
    """An application that keeps the newest status of a robot by its `time` must not take the `offline` of a clean
    stop (or a robot retired from the fleet) for older than the statuses before it."""
    model = rb1_model()
    port = SimPort(model, sim(0.3))
    port.watched = True
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/status"])
    engine = serve(model, port, config(broker))
    try:
        app.wait(lambda ev: any(s.get("robot") == "present" for s in statuses(ev)))
        port.down = True
        app.wait(lambda ev: statuses(ev)[-1].get("robot") == "absent", timeout=5)
    finally:
        engine.stop()
    app.wait(lambda ev: statuses(ev)[-1]["state"] == "offline", timeout=5)
    times = [e["time"] for t, e in app.events if t == f"td2adaptor/{ROBOT}/status"]
    app.close()
    assert times[-1] >= max(times), times  # ISO 8601 UTC with milliseconds: text order is time order


def test_the_robots_of_a_process_are_looked_at_together_once_per_period_not_each_on_its_own(
    broker: Mosquitto,
) -> None:
    """A fleet's idle process woke three threads per robot and period for its looks (the robot's timer on the
    loop, its look on the call pool, its answer posted back: 300 wake-ups a second for 100 robots, each for
    microseconds of work). Now the robots of one process are looked at together: one pool task per period,
    whatever the number of robots, and each robot's status still follows its own ROS side."""
    from td2adaptor.runtime.loop import acquire, release

    model = rb1_model()
    robots = [f"pres_many_{i}" for i in range(8)]
    ports = {robot: SimPort(model, sim(0.3)) for robot in robots}
    for port in ports.values():
        port.watched = True
    app = AppClient(broker, ["td2adaptor/+/status"])
    engines = [serve(model, ports[robot], config(broker, robot=robot)) for robot in robots]
    shared = acquire()
    submitted: list[float] = []
    submit = shared.pool.submit
    try:
        for robot in robots:
            app.wait(lambda ev: (statuses(ev, robot)[-1:] or [{}])[0].get("robot") == "present")  # noqa: B023
        shared.pool.submit = lambda task: (submitted.append(time.monotonic()), submit(task))[1]  # type: ignore[method-assign]
        time.sleep(1.0)  # ten periods of 0.1 s
        shared.pool.submit = submit  # type: ignore[method-assign]
        periods = 1.0 / 0.1
        assert len(submitted) <= periods + 3, f"{len(submitted)} pool tasks in {periods:.0f} periods for 8 robots"
        ports[robots[3]].down = True  # one robot's ROS side goes: only its status says so
        app.wait(lambda ev: statuses(ev, robots[3])[-1].get("robot") == "absent", timeout=5)
        assert all(statuses(app.events, r)[-1].get("robot") == "present" for r in robots if r != robots[3])
        ports[robots[3]].down = False
        app.wait(lambda ev: statuses(ev, robots[3])[-1].get("robot") == "present", timeout=5)
    finally:
        shared.pool.submit = submit  # type: ignore[method-assign]
        release(shared)
        for engine in engines:
            engine.stop()
        app.close()
