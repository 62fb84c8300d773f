"""A command read on a connection whose session another process took over before the engine handled it is left
to that process (issue 32, engine.py `_dispatch`). A process of a shared fleet that hung (SIGSTOP) resumes and
reads what waited in its socket; the broker had meanwhile given the robot's session, and those commands, to the
process that took the robot over. On one host both share the robot's replay guard and mission ledger
(`state_dir`): had the resumed process taken the command (guard, ledger, its answer written on no connection),
the new owner would find it handled by another run and answer nothing (a whole-suite run at load 20-28 left two
robots' invokes unanswered this way, and loops of test_fleet_share.py's hang test at load 10-16 three of eight).

Real mosquitto, real engines (`serve`, as `run` starts them) and one real state directory; the engines' shared
loop is held, so the order is the one of the failure: the first process's engine handles the command after its
connection was lost, the new owner's after that.
"""

from __future__ import annotations

import json
import threading
import uuid
from pathlib import Path
from typing import Any

import pytest

from td2adaptor.runtime import loop
from td2adaptor.runtime.config import load_defaults, robot_config
from td2adaptor.runtime.engine.engine import Engine
from td2adaptor.runtime.engine.ledger import Ledger
from td2adaptor.runtime.engine.replay import ReplayGuard, Verdict, digest
from td2adaptor.runtime.events import now_rfc3339
from td2adaptor.runtime.node.app import serve
from td2adaptor.runtime.ros.port import StartResult
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.broker import Mosquitto
from tests.runtime.client import AppClient
from tests.runtime.edge import bus_of, until
from tests.runtime.rb1 import rb1_model, sim

ROBOT = "rb_00"
INVOKE = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"


class CountingPort(SimPort):
    """A simulated robot that counts the missions it starts (over both processes: they share nothing else)."""

    starts: list[Any]

    def start(self, component: str, action: str, payload: Any, timeout: float) -> StartResult:
        self.starts.append(payload)
        return super().start(component, action, payload, timeout)


def test_a_command_read_on_a_connection_whose_session_moved_is_left_to_the_new_owner(tmp_path: Path) -> None:
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    settings = {"bus": broker.url, "poll_period": 0.05, "property_period": 0, "presence_period": 0}
    defaults = load_defaults(env={}, overrides={**settings, "state_dir": str(tmp_path / "state")})
    config = robot_config(defaults, ROBOT)
    model = rb1_model()
    starts: list[Any] = []

    def port() -> CountingPort:
        p = CountingPort(model, sim(0.3))
        p.starts = starts
        return p

    app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
    shared = loop.acquire()  # the process's loop, which both engines run on
    free = threading.Event()
    engines: list[Engine] = []
    second: list[Engine] = []
    starting: threading.Thread | None = None
    try:
        first = serve(model, port(), config)
        engines.append(first)
        held = threading.Event()

        def hold() -> None:  # on the loop: nothing else runs there until `free`
            held.set()
            free.wait(60)

        shared.loop.post(hold)
        assert held.wait(10)
        event_id = uuid.uuid4().hex
        event = {
            "id": event_id,
            "time": now_rfc3339(),
            "correlation": event_id,
            "payload": {"procedure": {"goals": [{"pose": {"x": 1.5, "y": 3.0}}]}},
        }
        app.send(INVOKE, event)
        assert until(lambda: first._queued >= 1, 20)  # read on the first connection, waiting for the loop

        # another process on this host takes the robot over: the same client id, the same state directory; the
        # broker closes the first connection and gives the session, with the unacknowledged command, to it
        def take_over() -> None:
            engines.append(serve(model, port(), config, prepare=second.append))

        starting = threading.Thread(target=take_over, daemon=True)
        starting.start()
        assert until(lambda: not bus_of(first).connected, 20)  # the first process learnt its connection is gone
        assert until(lambda: bool(second) and second[0]._queued >= 1, 20)  # the new owner got the command too
        free.set()  # the first process's engine comes to the command first, then the new owner's

        def ended() -> list[dict[str, Any]]:
            return [
                e["payload"]
                for _t, e in list(app.events)
                if e.get("type") == "feedback" and e.get("correlation") == event_id and e["payload"].get("terminal")
            ]

        assert until(lambda: bool(ended()), 30), (app.events, starts)
        assert [p["state"] for p in ended()] == ["finished"], ended()
        assert len(starts) == 1, starts  # run once, by the new owner
    finally:
        free.set()
        if starting is not None:
            starting.join(30)
        for engine in engines:
            engine.stop()
        loop.release(shared)
        app.close()
        broker.stop()


@pytest.mark.parametrize(
    ("queued", "handed"),
    [(False, False), (True, False), (True, True)],
    ids=["no-feedback-yet", "queued-already", "handed-over-before-the-end"],
)
def test_an_invoke_another_run_took_but_has_not_ended_is_answered_with_its_end_once_written(
    tmp_path: Path, queued: bool, handed: bool
) -> None:
    """The other order (the resumed process came to the command just before it learnt its connection was gone):
    the other run has the id and the invoke's mission open in the robot's store, and no answer yet; the answer it
    writes would go on no connection. The process that holds the session now answers with that end once the
    ledger has it (before, it answered nothing: "its first feedback event, about to come, answers it"). The other
    run is the guard and ledger another process's engine writes, on the same state directory. `handed`: the
    process stops serving the robot before that end is written (a hand-over a moment after its takeover): it
    leaves the invoke unacknowledged, and the robot's next connection answers it (before, it was acknowledged and
    nobody answered it)."""
    broker = Mosquitto(tmp_path / "broker")
    broker.start()
    settings = {"bus": broker.url, "poll_period": 0.05, "property_period": 0, "presence_period": 0}
    defaults = load_defaults(env={}, overrides={**settings, "state_dir": str(tmp_path / "state")})
    config = robot_config(defaults, ROBOT)
    model = rb1_model()
    starts: list[Any] = []
    port = CountingPort(model, sim(0.3))
    port.starts = starts
    app = AppClient(broker, [f"td2adaptor/{ROBOT}/#"])
    engine = serve(model, port, config)
    engines = [engine]
    assert config.ids_file is not None
    guard = ReplayGuard(config.ids_file, window=config.freshness_window, skew=config.clock_skew)
    ledger = Ledger(config.ids_file, keep=60)
    try:
        event_id = uuid.uuid4().hex
        sent = now_rfc3339()
        event = {
            "id": event_id,
            "time": sent,
            "correlation": event_id,
            "payload": {"procedure": {"goals": [{"pose": {"x": 2.5, "y": 3.0}}]}},
        }
        assert guard.check(event_id, INVOKE, sent, digest(event)) is Verdict.NEW  # the other run took it first
        key = ledger.open(
            event_id=event_id,
            topic=INVOKE,
            kind="procedure",
            component="GoToComponent",
            action="gotoRun",
            correlation=event_id,
        )
        first = {"state": "queued", "result": "ok", "terminal": False, "seq": 1}
        if queued:  # the other run's first feedback (a procedure's start), before it learnt its connection was gone
            ledger.event(
                key,
                mission=None,
                goal=None,
                state="queued",
                seq=1,
                reserved=1,
                latest=json.dumps(
                    {"type": "feedback", "id": uuid.uuid4().hex, "correlation": event_id, "payload": first}
                ),
                terminal=False,
            )
        app.send(INVOKE, event)
        assert until(lambda: engine.idle() and engine.outbox.stats.get("duplicates", 0) >= 1, 20)
        end = {
            "type": "feedback",
            "affordance": "gotoRun",
            "robot": ROBOT,
            "id": uuid.uuid4().hex,
            "time": now_rfc3339(),
            "source": f"td2adaptor/{ROBOT}",
            "correlation": event_id,
            "payload": {
                "state": "failed",
                "message": "not run here",
                "reason": "unreachable",
                "terminal": True,
                "seq": 2,
            },
        }
        if handed:  # this process hands the robot over before the other run wrote the end
            engine.stop()
            engines.remove(engine)
        # the other run ends it, and publishes its end on a connection that is gone
        ledger.event(
            key, mission=None, goal=None, state="failed", seq=2, reserved=2, latest=json.dumps(end), terminal=True
        )
        ledger.done(key)
        if handed:  # the robot's next connection (its next owner) gets the invoke again
            engines.append(serve(model, port, config))

        def ended() -> list[dict[str, Any]]:
            return [e for _t, e in list(app.events) if e.get("type") == "feedback" and e.get("correlation") == event_id]

        def terminal() -> list[dict[str, Any]]:
            return [e for e in ended() if e["payload"].get("terminal")]

        assert until(lambda: bool(terminal()), 20), app.events
        assert [e["id"] for e in terminal()] == [end["id"]]  # that run's end, as it wrote it
        assert [e["payload"]["seq"] for e in ended()] == ([1, 2] if queued else [2])
        assert starts == []  # not run here: the other run took it
    finally:
        guard.close()
        ledger.close()
        for served in engines:
            served.stop()
        app.close()
        broker.stop()
