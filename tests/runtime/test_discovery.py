"""Discovery: the edge node registers each robot's TD with a real W3C WoT Thing Description Directory (Domus TDD
on Oxigraph, from PyPI, tests/runtime/tdd.py) while it serves the robot (the simulated RB-1) on a real
mosquitto: listed and given back equal to the TD published on the broker, replaced when the TD changed, gone
when the node stops, expired when the node dies; a directory that does not answer or refuses is reported in
the log and the robot is served all the same."""

from __future__ import annotations

import logging
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.model import Model
from td2adaptor.runtime import RuntimeConfig, serve
from td2adaptor.runtime.ros.simport import SimPort
from tests.conftest import REPO
from tests.ports import free_port
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import until
from tests.runtime.rb1 import GOAL, compile_td, rb1_model, sim, terminal
from tests.runtime.tdd import TddServer, as_registered, semantic, small_robot_td

ROBOT = "rb1_disco"  # each test its own robot, so that none sees another's registration


def thing_id(robot: str) -> str:
    return f"urn:dev:wot:robotnik:rb1:{robot}"


@pytest.fixture(scope="module")
def directory(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TddServer]:
    server = TddServer(tmp_path_factory.mktemp("tdd"))
    server.start()
    yield server
    server.stop()


@pytest.fixture(scope="module")
def model(tmp_path_factory: pytest.TempPathFactory) -> Model:
    return compile_td(small_robot_td(tmp_path_factory.mktemp("td")))


def config(url: str, robot: str, **kw: Any) -> RuntimeConfig:
    base: dict[str, Any] = {"robot": robot, "bus": url, "poll_period": 0.05, "property_period": 0, "state_dir": ""}
    return RuntimeConfig(**{**base, **kw})


def published_td(app: AppClient, robot: str) -> dict[str, Any]:
    """The TD retained on the robot's td topic (waited for)."""
    topic = f"td2adaptor/{robot}/td"
    events = app.wait(lambda ev: any(t == topic and "id" in e for t, e in ev), 20)
    return next(e for t, e in events if t == topic and "id" in e)


READ_BACK = "cannot give it back"


def test_the_robot_td_is_registered_listed_given_back_as_published_and_removed_on_stop(
    directory: TddServer, broker: Mosquitto, model: Model, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="td2adaptor.runtime")
    robot, thing = ROBOT, thing_id(ROBOT)
    engine = serve(model, SimPort(model, sim()), config(broker.url, robot, directory=directory.url, directory_ttl=120))
    app = AppClient(broker.url, [f"td2adaptor/{robot}/td"])
    try:
        td = published_td(app, robot)
        assert td["id"] == thing
        assert until(lambda: thing in directory.ids(), 30), directory.output()
        registered = directory.thing(thing)
        assert registered is not None
        assert registered["registration"]["discovery:ttl"] == 120 and "expires" in registered["registration"]
        assert "https://www.w3.org/2022/wot/discovery" in registered["@context"]
        # what the directory keeps is the TD on the broker (as RDF keeps it: arrays are sets there)
        assert semantic(as_registered(registered)) == semantic(td)
        hrefs = {f["href"] for f in td["actions"]["gotoRun"]["forms"]}
        assert {f["href"] for f in registered["actions"]["gotoRun"]["forms"]} == hrefs  # the topics, as published
        # the node read it back after registering it (GET 200): nothing to say about it
        assert until(lambda: "registered with" in caplog.text, 10)
        assert directory.status("GET", f"/things/{thing}") == 200
    finally:
        engine.stop()  # deregisters first, then clears the retained TD
        app.close()
    assert thing not in directory.ids()
    assert directory.thing(thing) is None
    assert READ_BACK not in caplog.text and not [r for r in caplog.records if r.levelno >= logging.WARNING]


def test_the_whole_rb1_registers_too_and_the_directory_holds_every_form_of_it(
    directory: TddServer, broker: Mosquitto, caplog: pytest.LogCaptureFixture
) -> None:
    """The full RB-1 TD: Domus stores it, but cannot frame it as JSON again (tests/runtime/tdd.py), so what it
    holds is read as RDF: the Thing, and every form's href and topic of the TD on the broker. The node reads it
    back after registering it and says, once, what the directory's 500 means; it keeps serving the robot."""
    caplog.set_level(logging.INFO, logger="td2adaptor.runtime")
    robot = ROBOT + "_full"
    thing = thing_id(robot)
    model = rb1_model()
    engine = serve(model, SimPort(model, sim()), config(broker.url, robot, directory=directory.url))
    app = AppClient(broker.url, [f"td2adaptor/{robot}/#"])
    try:
        td = published_td(app, robot)
        assert until(lambda: directory.triples(thing) is not None, 60), directory.output()
        triples = directory.triples(thing) or ""
        assert (
            f"<{thing}> <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> <https://www.w3.org/2019/wot/td#Thing>"
            in triples
        )
        forms = [f for kind in ("properties", "actions", "events") for a in td[kind].values() for f in a["forms"]]
        assert len(forms) >= 25  # one per affordance, a run action's also for its query and cancel
        for form in forms:
            assert f'"{form["href"]}"' in triples or f"<{form['href']}>" in triples, form["href"]
            topic = form.get("mqv:topic") or form["mqv:filter"]
            assert f'"{topic}"' in triples, topic
        # too large for Domus to give back as JSON: its N-Triples pass Linux's limit for one argument
        assert len(triples.encode("utf-8")) > 131_072
        assert directory.status("GET", f"/things/{thing}") == 500
        assert until(lambda: READ_BACK in caplog.text, 60), caplog.text
        (line,) = [r.getMessage() for r in caplog.records if READ_BACK in r.getMessage()]
        assert f"robot {robot}: the directory {directory.url} stored its Thing Description {thing}" in line
        assert "GET " in line and "HTTP 500" in line and "<" not in line, line  # the page's words, not its HTML
        assert "stored and searchable there (SPARQL), but not readable as JSON" in line, line
        # ...and serves the robot all the same
        app.send(f"td2adaptor/{robot}/GoToComponent/gotoRun", {"correlation": "after", "payload": GOAL})
        app.wait(terminal("feedback", "after"), 30)
    finally:
        engine.stop()
        app.close()
    assert directory.triples(thing) is None


def node(
    broker: Mosquitto, robot: str, td: Path, directory: TddServer, ttl: int, td_broker: str
) -> subprocess.Popen[str]:
    args = [broker.url, robot, str(td), directory.url, str(ttl), td_broker]
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.runtime.discovery_proc", *args],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "ready", proc.stderr
    return proc


def href(td: dict[str, Any] | None) -> str:
    """gotoRun's href in a registered TD ("" for none)."""
    return "" if td is None else str(td["actions"]["gotoRun"]["forms"][0]["href"])


def test_a_changed_td_replaces_the_registration_and_a_dead_nodes_td_expires(
    directory: TddServer, broker: Mosquitto, tmp_path: Path
) -> None:
    td = small_robot_td(tmp_path)
    robot = ROBOT + "_b"
    thing = thing_id(robot)
    first = node(broker, robot, td, directory, 60, f"mqtt://127.0.0.1:{broker.port}")
    try:
        wanted = f"mqtt://127.0.0.1:{broker.port}/"
        assert until(lambda: href(directory.thing(thing)).startswith(wanted), 30), directory.output()
    finally:
        first.kill()  # dies without deregistering
        first.communicate(timeout=10)
    assert directory.thing(thing) is not None  # a dead node's TD stays until it expires (ttl 60 s)
    # the robot comes back with another TD (its broker named differently): PUT replaces the registration
    # ttl 20 s, refreshed every 10 s: a refresh that Domus would still be storing when its sweep finds the TD
    # expired makes the sweep fail and Domus never sweeps again. With ttl 10 (refresh every 5 s) a loaded
    # machine delayed a refresh that long (1 of ~10 loaded suite runs: FusekiError in Domus's sweep thread);
    # 10 s leaves room for that
    second = node(broker, robot, td, directory, 20, f"mqtt://localhost:{broker.port}")
    try:
        wanted = f"mqtt://localhost:{broker.port}/"
        assert until(lambda: href(directory.thing(thing)).startswith(wanted), 30), directory.output()
        assert until(lambda: directory.ids().count(thing) == 1, 30)  # once (a refresh briefly removes it)
        assert until(lambda: ttl_of(directory.thing(thing)) == 20, 30)
    finally:
        second.kill()
        second.communicate(timeout=10)
        before = len(directory.domus_log())
    # ...and gone once the ttl has passed without a refresh: Domus's sweep (every second) finds it expired
    try:
        swept = f"expired tds to clean:  ['td:{thing}']"
        assert until(lambda: swept in directory.domus_log()[before:], 40), directory.output()
        assert until(lambda: directory.thing(thing) is None, 10)  # Domus says so before it deletes it
    finally:
        # Domus 1.0.2's sweep leaves the expired TD's listing metadata behind (GET /things then fails with a
        # KeyError of its own); a DELETE of the id removes it, so the next test gets a clean directory
        assert directory.status("DELETE", f"/things/{thing}") in (200, 204)
    assert thing not in directory.ids()


def ttl_of(td: dict[str, Any] | None) -> Any:
    """The ttl of a registered TD (None for none, or while a refresh has it half written)."""
    return None if td is None else td.get("registration", {}).get("discovery:ttl")


@pytest.mark.parametrize("where", ["refusing connections", "answering 404"])
def test_a_directory_that_fails_is_reported_and_the_robot_is_served(
    directory: TddServer, broker: Mosquitto, model: Model, caplog: pytest.LogCaptureFixture, where: str
) -> None:
    url = f"http://127.0.0.1:{free_port()}" if where == "refusing connections" else f"{directory.url}/nowhere"
    token = "s3cret-token-value"
    caplog.set_level(logging.INFO, logger="td2adaptor.runtime")
    robot = ROBOT + "_c"
    engine = serve(model, SimPort(model, sim(0.2)), config(broker.url, robot, directory=url, directory_token=token))
    app = AppClient(broker.url, [f"td2adaptor/{robot}/#"])
    try:
        published_td(app, robot)
        app.send(
            f"td2adaptor/{robot}/GoToComponent/gotoRun", {"correlation": "served", "payload": GOAL}
        )  # the robot is served all the same
        app.wait(terminal("feedback", "served"))
        assert until(lambda: "could not register" in caplog.text, 10)
    finally:
        engine.stop()
        app.close()
    (line,) = [r.getMessage() for r in caplog.records if "could not register" in r.getMessage()][:1]
    assert f"robot {robot}:" in line and "attempt 1" in line and "the robot is served all the same" in line
    expected = "no answer (" if where == "refusing connections" else "the directory answered HTTP 404"
    assert f"PUT {url}/things/" in line and expected in line, line
    assert token not in caplog.text
    assert directory.thing(thing_id(robot)) is None


def test_the_registration_says_whether_the_robot_is_there(
    directory: TddServer, broker: Mosquitto, model: Model
) -> None:
    """The robot's ROS side (its status `robot`, issue 32) is registered with its TD and registered again when
    it changes: a directory query can find the robots that are there now."""
    robot, thing = "rb1_disco_presence", thing_id("rb1_disco_presence")
    port = SimPort(model, sim())
    port.watched = True  # `down` is the robot's ROS side gone
    engine = serve(
        model, port, config(broker.url, robot, directory=directory.url, directory_ttl=120, presence_period=0.1)
    )

    def presence() -> Any:
        registered = directory.thing(thing) or {}
        return next((v for k, v in registered.items() if k.endswith("presence")), None)

    try:
        assert until(lambda: presence() == "present", 30), directory.thing(thing)
        port.down = True
        assert until(lambda: presence() == "absent", 30), directory.thing(thing)
        port.down = False
        assert until(lambda: presence() == "present", 30), directory.thing(thing)
    finally:
        engine.stop()
    assert thing not in directory.ids()
