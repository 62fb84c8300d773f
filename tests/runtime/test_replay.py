"""Commands are fresh and unique (issue 16, findings 3-5): a stale command is answered, not run; an id is
handled once however many events come between and across a restart; an id reused on another topic, or on
the same topic with other content, is answered with an error."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from td2adaptor.runtime import LocalBroker, RuntimeConfig, serve
from td2adaptor.runtime.engine.replay import ReplayGuard, Verdict, digest, now_text, parse_time, time_problem
from td2adaptor.runtime.ros.simport import SimPort
from tests.runtime.rb1 import GOAL, LocalApp, check_outbound, rb1_model, sim, terminal

ROBOT = "rb1_base_a"
GOTO = f"td2adaptor/{ROBOT}/GoToComponent/gotoRun"
QUERY = f"td2adaptor/{ROBOT}/GoToComponent/gotoQuery"


class Clock:
    def __init__(self, now: float) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


def test_the_guard_decides_by_time_id_and_topic(tmp_path: Path) -> None:
    clock = Clock(parse_time("2026-11-23T12:00:00Z") or 0.0)
    guard = ReplayGuard(tmp_path / "ids.sqlite3", window=300, skew=30, clock=clock)
    assert guard.check("a", "t/1", "2026-11-23T11:59:00Z") is Verdict.NEW
    assert guard.check("a", "t/1", "2026-11-23T11:59:00Z") is Verdict.DUPLICATE
    assert guard.check("a", "t/2", "2026-11-23T11:59:00Z") is Verdict.REUSED
    assert guard.check("old", "t/1", "2001-01-01T00:00:00Z") is Verdict.EXPIRED
    assert guard.check("late", "t/1", "2026-11-23T11:55:01Z") is Verdict.NEW  # 299 s: inside the window
    assert guard.check("ahead", "t/1", "2026-11-23T12:00:29+00:00") is Verdict.NEW  # within the skew
    assert guard.check("future", "t/1", "2026-11-23T13:00:00+01:00") is Verdict.NEW  # the same instant
    assert guard.check("future2", "t/1", "2026-11-23T12:01:00Z") is Verdict.FUTURE
    assert guard.check(None, "t/1", None) is Verdict.NEW
    # durable: a new guard on the same file (a restart) knows the ids
    guard.close()
    again = ReplayGuard(tmp_path / "ids.sqlite3", window=300, skew=30, clock=clock)
    assert again.check("a", "t/1", "2026-11-23T11:59:00Z") is Verdict.INHERITED  # the earlier run's
    again.adopt("a", "t/1", "2026-11-23T11:59:00Z")
    assert again.check("a", "t/1", "2026-11-23T11:59:00Z") is Verdict.DUPLICATE  # this run's now
    # bounded by the window, not a count: once every remembered id is too old to be fresh, it is dropped
    clock.now += 3600
    assert again.check("b", "t/1", None) is Verdict.NEW
    assert len(again) == 1
    again.close()


def test_the_same_id_on_the_same_topic_with_other_content_is_reused_not_a_redelivery(tmp_path: Path) -> None:
    """Audit gap 6: the guard keyed on id and topic, so another command under a used id was dropped in silence."""
    clock = Clock(parse_time("2026-11-23T12:00:00Z") or 0.0)
    guard = ReplayGuard(tmp_path / "ids.sqlite3", window=300, skew=30, clock=clock)
    sent = "2026-11-23T11:59:00Z"
    assert guard.check("a", "t/1", sent, digest="d1") is Verdict.NEW
    assert guard.check("a", "t/1", sent, digest="d1") is Verdict.DUPLICATE  # a redelivery, byte for byte
    assert guard.check("a", "t/1", sent, digest="d2") is Verdict.REUSED  # other content under the same id
    assert guard.check("a", "t/2", sent, digest="d1") is Verdict.REUSED  # another topic, as before
    guard.close()
    again = ReplayGuard(tmp_path / "ids.sqlite3", window=300, skew=30, clock=clock)  # durable, with the digest
    assert again.check("a", "t/1", sent, digest="d1") is Verdict.INHERITED
    assert again.check("a", "t/1", sent, digest="d2") is Verdict.REUSED
    again.close()


def test_a_store_written_before_digests_still_knows_its_ids(tmp_path: Path) -> None:
    import sqlite3

    path = tmp_path / "ids.sqlite3"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE seen (id TEXT PRIMARY KEY, topic TEXT NOT NULL, until REAL)")
    db.execute("INSERT INTO seen VALUES ('old', 't/1', ?)", (time.time() + 300,))
    db.commit()
    db.close()
    guard = ReplayGuard(path, window=300, skew=30)
    assert guard.check("old", "t/1", None, digest="any") is Verdict.INHERITED  # content unknown: as before
    assert guard.check("old", "t/2", None, digest="any") is Verdict.REUSED
    assert guard.check("new", "t/1", None, digest="d") is Verdict.NEW
    assert guard.check("new", "t/1", None, digest="e") is Verdict.REUSED
    guard.close()


def test_many_events_do_not_push_an_id_out_while_it_could_be_fresh(tmp_path: Path) -> None:
    guard = ReplayGuard(None, window=300, skew=30)
    sent = now_text()
    assert guard.check("replayed", "t/x", sent) is Verdict.NEW
    for i in range(10_050):
        assert guard.check(f"other-{i}", "t/x", sent) is Verdict.NEW
    assert guard.check("replayed", "t/x", sent) is Verdict.DUPLICATE


def test_the_freshness_window_is_the_cut_off_the_docs_give(tmp_path: Path) -> None:
    """Issue 30, item 4: the node refused an event only once it was older than the window plus the clock skew
    (330 s by default) while the docs, the configuration and the refusal itself say the window (300 s). The
    window is the cut-off by the node's clock; the skew lets a sender's clock run ahead, not behind."""
    clock = Clock(parse_time("2026-11-23T12:00:00Z") or 0.0)
    guard = ReplayGuard(None, window=300, skew=30, clock=clock)
    assert guard.check("in", "t/1", "2026-11-23T11:55:00Z") is Verdict.NEW  # 300 s: the last fresh second
    assert guard.check("out", "t/1", "2026-11-23T11:54:59.900Z") is Verdict.EXPIRED  # 300.1 s
    assert guard.check("out2", "t/1", "2026-11-23T11:54:31Z") is Verdict.EXPIRED  # 329 s ran before
    assert guard.check("ahead", "t/1", "2026-11-23T12:00:30Z") is Verdict.NEW  # the skew, ahead
    assert guard.check("ahead2", "t/1", "2026-11-23T12:00:30.1Z") is Verdict.FUTURE


#: times with the shape of RFC 3339 that name no instant (issue 30, item 4: each ran without a freshness check)
NOT_INSTANTS = {
    "2026-13-01T00:00:00Z": "month 13",
    "2026-02-30T12:00:00Z": "February 2026 has no day 30",
    "2024-02-30T12:00:00Z": "February 2024 has no day 30",
    "2026-04-31T12:00:00Z": "April 2026 has no day 31",
    "2026-05-01T24:00:00Z": "hour 24",
    "2026-05-01T12:60:00Z": "minute 60",
    "2026-05-01T12:00:60Z": "second 60",
    "2026-05-01T12:00:00+99:99": "offset +99:99",
    "2026-05-01T12:00:00-24:00": "offset -24:00",
    "2026-00-01T12:00:00Z": "month 00",
    "2026-05-00T12:00:00Z": "day 00",
    "0000-05-01T12:00:00Z": "year 0000",
}


def test_a_time_that_is_no_real_instant_is_refused_by_the_guard() -> None:
    guard = ReplayGuard(None, window=300, skew=30)
    for text, why in NOT_INSTANTS.items():
        assert parse_time(text) is None, text
        assert why in (time_problem(text) or ""), (text, time_problem(text))
        assert guard.check(f"id-{text}", "t/1", text) is Verdict.BAD_TIME, text
        assert guard.check(None, "t/1", text) is Verdict.BAD_TIME, text
    assert guard.check("leap-year", "t/1", "2024-02-29T12:00:00Z") is Verdict.EXPIRED  # a real day, long ago
    assert time_problem("2024-02-29T23:59:59.999999999+23:59") is None
    assert time_problem("2026-05-01t12:00:00z") is None  # RFC 3339 allows lower case
    assert time_problem("2026-05-01 12:00:00Z") is not None and time_problem("٢٠٢٦-05-01T12:00:00Z") is not None


def test_a_command_whose_time_is_no_real_instant_is_answered_and_not_run(tmp_path: Path) -> None:
    """Even with `require_id_and_time`, a malformed time skipped the freshness check and the command ran: it is
    refused with an error event that names the member and says what is wrong with it."""
    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    port = SimPort(model, robot)
    app = LocalApp(broker)
    engine = serve(model, port, _config(tmp_path, require_id_and_time=True), broker=broker)
    try:
        for i, (text, why) in enumerate(NOT_INSTANTS.items()):
            app.send(GOTO, {"id": f"bad-{i}", "correlation": f"bad-{i}", "time": text, "payload": GOAL})
            app.wait(lambda ev, c=f"bad-{i}": bool(app.of("error", c)))
            (error,) = app.of("error", f"bad-{i}")
            assert error["payload"]["code"] == "invalid-event", error
            assert "`time`" in error["payload"]["message"] and why in error["payload"]["message"], error
            assert error["payload"]["errors"] == [{"path": "/time", "message": time_problem(text)}]
        app.send(GOTO, {"id": "good", "correlation": "good", "time": now_text(), "payload": GOAL})
        app.wait(terminal("feedback", "good"))
        assert [c for c in port.calls if c[1] == "gotoRun"] == [("GoToComponent", "gotoRun")]  # the good one
        assert not [e for e in app.of("feedback") if e.get("correlation", "").startswith("bad-")]
    finally:
        engine.stop()
    check_outbound(app.events)


def _config(state: Path, **kw: Any) -> RuntimeConfig:
    base: dict[str, Any] = {"robot": ROBOT, "poll_period": 0.02, "property_period": 0, "call_timeout": 1.0}
    return RuntimeConfig(**{**base, "state_dir": str(state), **kw})


def test_a_stale_command_is_answered_and_the_robot_does_not_move(tmp_path: Path) -> None:
    broker, model, robot = LocalBroker(), rb1_model(), sim(0.1)
    app = LocalApp(broker)
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:
        app.send(GOTO, {"id": "stale", "correlation": "c1", "time": "2001-01-01T00:00:00Z", "payload": GOAL})
        app.wait(lambda ev: bool(app.of("error", "c1")))
        (error,) = app.of("error", "c1")
        assert error["payload"]["code"] == "expired" and "freshness window" in error["payload"]["message"]
        time.sleep(0.2)
        assert (robot.x, robot.y) == (0.0, 0.0) and not app.of("feedback", "c1")
    finally:
        engine.stop()
    check_outbound(app.events)


def test_a_replay_after_a_restart_runs_once_and_a_reused_id_is_answered(tmp_path: Path) -> None:
    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    invoke = {"id": "once", "correlation": "c2", "time": now_text(), "payload": GOAL}
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:
        app.send(GOTO, invoke)
        app.wait(terminal("feedback", "c2"))
    finally:
        engine.stop()
    runs = len(app.of("feedback", "c2"))
    # the node restarts (same state directory) and the broker delivers the same invoke again, byte for byte
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    reads: list[str] = []
    latest = engine.ledger.latest

    def counted(event_id: str, topic: str) -> Any:
        reads.append(event_id)
        return latest(event_id, topic)

    engine.ledger.latest = counted  # type: ignore[method-assign]
    try:
        app.send(GOTO, invoke)
        app.send(QUERY, {"id": "once", "correlation": "c3", "time": now_text()})
        app.wait(lambda ev: bool(app.of("error", "c3")))
        (error,) = app.of("error", "c3")
        assert error["payload"]["code"] == "id-reused" and "'once'" in error["payload"]["message"]
        # no second mission: the invoke is answered with its terminal event again (the same event)
        app.wait(lambda ev: len(app.of("feedback", "c2")) > runs)
        time.sleep(0.2)
        feedback = app.of("feedback", "c2")
        assert len(feedback) == runs + 1 and feedback[-1] == feedback[runs - 1] and feedback[-1]["payload"]["terminal"]
        assert engine.stats.get("duplicates") == 1
        assert reads == ["once"]  # the earlier run's mission read from the ledger once: taken, and its answer
    finally:
        engine.stop()
    check_outbound(app.events)


def test_another_command_under_a_used_id_is_answered_and_not_run(tmp_path: Path) -> None:
    """Audit gap 6 through the engine: the same id and topic with another goal gets `id-reused`; the same
    bytes again (a redelivery) are not run, only answered with the terminal event again; an equal event with
    its keys in another order is the same content."""
    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    sent = now_text()
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:
        first = {"id": "one-id", "correlation": "c4", "time": sent, "payload": GOAL}
        app.send(GOTO, first)
        app.wait(terminal("feedback", "c4"))
        runs = len(app.of("feedback", "c4"))
        app.send(GOTO, dict(reversed(list(first.items()))))  # the same event, serialised otherwise
        other = {**first, "correlation": "c5"}
        app.send(GOTO, other)
        app.wait(lambda ev: bool(app.of("error", "c5")))
        (error,) = app.of("error", "c5")
        assert error["payload"]["code"] == "id-reused" and "'one-id'" in error["payload"]["message"]
        time.sleep(0.2)
        feedback = app.of("feedback", "c4")  # the redelivery: not run, answered with the terminal event again
        assert len(feedback) == runs + 1 and feedback[-1] == feedback[runs - 1] and not app.of("feedback", "c5")
        assert not app.of("error", "c4")
        assert engine.stats.get("duplicates") == 1
    finally:
        engine.stop()
    check_outbound(app.events)


def test_require_id_and_time_refuses_what_the_guard_cannot_protect(tmp_path: Path) -> None:
    """Audit gaps 1-2, opt-in: with `require_id_and_time`, an envelope command without `id` or `time` is
    answered `no-id-or-time` and not run; a WoT command needs a correlationId, which becomes its event id, so a
    replay of it is a redelivery (not run) and another goal under it is `id-reused`."""
    from td2adaptor.model.wot import CORRELATION, WOT_LEVEL

    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    wot_goto = f"td2adaptor/{ROBOT}/{WOT_LEVEL}/GoToComponent/gotoRun"
    engine = serve(model, SimPort(model, robot), _config(tmp_path, require_id_and_time=True), broker=broker)
    try:
        app.send(GOTO, {"correlation": "no-id", "time": now_text(), "payload": GOAL})
        app.send(GOTO, {"id": "no-time", "correlation": "no-time", "payload": GOAL})
        app.send(wot_goto, GOAL)  # a WoT command without correlationId
        app.wait(lambda ev: len(app.of("error")) >= 3)
        codes = [e["payload"]["code"] for e in app.of("error")]
        assert codes == ["no-id-or-time"] * 3, codes
        assert "require_id_and_time" in app.of("error", "no-time")[0]["payload"]["message"]
        time.sleep(0.2)
        assert (robot.x, robot.y) == (0.0, 0.0) and not app.of("feedback")
        app.send(GOTO, {"id": "both", "correlation": "both", "time": now_text(), "payload": GOAL})
        app.wait(terminal("feedback", "both"))
        app.send(wot_goto, {**GOAL, CORRELATION: "wot-1"})
        app.wait(terminal("feedback", "wot-1"))
        runs = len(app.of("feedback", "wot-1"))
        app.send(wot_goto, {**GOAL, CORRELATION: "wot-1"})  # replayed: a redelivery, not run
        other = {"procedure": {"goals": [{"pose": {"x": 2.0, "y": 1.0, "theta": 0.0}}]}}
        app.send(wot_goto, {**other, CORRELATION: "wot-1"})  # another goal under the same id
        app.wait(lambda ev: bool(app.of("error", "wot-1")))
        assert app.of("error", "wot-1")[0]["payload"]["code"] == "id-reused"
        # a WoT consumer's command: told on the WoT error topic, in its terms (its id is its correlationId)
        wot_error = f"td2adaptor/{ROBOT}/{WOT_LEVEL}/error"
        app.wait(lambda ev: any(t == wot_error and e.get("code") == "id-reused" for t, e in ev))
        (reused,) = [e for t, e in app.events if t == wot_error and e.get("code") == "id-reused"]
        assert reused["topic"] == wot_goto and "correlationId 'wot-1' was already used" in reused["message"]
        time.sleep(0.2)
        feedback = app.of("feedback", "wot-1")  # the replay: not run, answered with the terminal event again
        assert len(feedback) == runs + 1 and feedback[-1] == feedback[runs - 1]
        assert engine.stats.get("duplicates") == 1
    finally:
        engine.stop()
    check_outbound(app.events)


def test_without_require_id_and_time_a_replayed_wot_command_runs_again(tmp_path: Path) -> None:
    """The default, as docs/security.md says: a WoT message is stamped on arrival, so a replay runs."""
    from td2adaptor.model.wot import CORRELATION, WOT_LEVEL

    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    wot_goto = f"td2adaptor/{ROBOT}/{WOT_LEVEL}/GoToComponent/gotoRun"
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:

        def ended() -> int:
            return len([e for e in app.of("feedback", "twice") if e["payload"]["terminal"]])

        app.send(wot_goto, {**GOAL, CORRELATION: "twice"})
        app.wait(lambda ev: ended() == 1)
        app.send(wot_goto, {**GOAL, CORRELATION: "twice"})  # the same message again
        app.wait(lambda ev: ended() == 2)  # a second mission
        assert not app.of("error")
    finally:
        engine.stop()


def test_a_retained_command_is_refused_not_run_at_every_reconnect(tmp_path: Path) -> None:
    """A command (envelope or WoT) published retained would reach the node at each (re)subscription: refused."""
    from td2adaptor.model.wot import CORRELATION, WOT_LEVEL

    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    wot_goto = f"td2adaptor/{ROBOT}/{WOT_LEVEL}/GoToComponent/gotoRun"
    app.bus.publish(wot_goto, json.dumps({**GOAL, CORRELATION: "kept"}).encode(), retain=True)
    app.bus.publish(GOTO, json.dumps({"id": "r1", "correlation": "kept-env", "payload": GOAL}).encode(), retain=True)
    engine = serve(model, SimPort(model, robot), _config(tmp_path), broker=broker)
    try:
        app.wait(lambda ev: bool(app.of("error", "kept")) and bool(app.of("error", "kept-env")))
        for correlation in ("kept", "kept-env"):
            (error,) = app.of("error", correlation)
            assert error["payload"]["code"] == "retained" and "retain" in error["payload"]["message"]
        app.send(GOTO, {"id": "fresh", "correlation": "c2", "time": now_text(), "payload": GOAL})
        app.wait(terminal("feedback", "c2"))  # a command sent as usual still runs
        assert not app.of("feedback", "kept") and not app.of("feedback", "kept-env")
    finally:
        engine.stop()
    check_outbound(app.events)


def test_an_invoke_an_earlier_run_remembered_and_never_took_runs_once_and_a_query_is_answered(tmp_path: Path) -> None:
    """A node killed between remembering a command's id and taking it (it never acknowledged the command, so the
    broker gives it again; seen in 1 of ~10 kill -9 runs, test_command_acks.py): the next run finds the id
    remembered and no mission in the ledger. The invoke runs (once: a second redelivery is answered with its
    terminal event again) and a query is answered; before, both were ignored in silence (`duplicate`)."""
    broker, model, robot = LocalBroker(), rb1_model(), sim(0.05)
    app = LocalApp(broker)
    config = _config(tmp_path)
    invoke = {"id": "orphan", "correlation": "c6", "time": now_text(), "payload": GOAL}
    query = {"id": "orphan-q", "correlation": "c7", "time": now_text()}
    killed = ReplayGuard(config.ids_file, window=config.freshness_window, skew=config.clock_skew)
    for event_id, topic, event in (("orphan", GOTO, invoke), ("orphan-q", QUERY, query)):
        assert killed.check(event_id, topic, event["time"], digest(event)) is Verdict.NEW  # what the kill leaves
    killed.close()
    engine = serve(model, SimPort(model, robot), config, broker=broker)
    try:
        app.send(GOTO, invoke)
        app.wait(terminal("feedback", "c6"))
        states = [e["payload"]["state"] for e in app.of("feedback", "c6")]
        assert states == ["queued", "running", "finished"], states
        app.send(QUERY, query)
        app.wait(lambda ev: bool(app.of("state", "c7") or app.of("error", "c7")))
        app.send(GOTO, invoke)  # redelivered once more: answered again, not run again
        app.wait(lambda ev: len(app.of("feedback", "c6")) > len(states))
        time.sleep(0.3)
        again = app.of("feedback", "c6")[len(states) :]
        assert [e["payload"]["state"] for e in again] == ["finished"], again
        assert len(robot.components["GoToComponent"].procedures) == 1  # run once
    finally:
        engine.stop()
    check_outbound(app.events)


def test_two_runs_that_share_the_store_and_check_one_id_at_once_agree_on_who_has_it(tmp_path: Path) -> None:
    """Two processes of a shared fleet on one host share a robot's store (state_dir) and may both be given one
    command (a hung process that resumes reads what waited in its socket after the session moved): the second
    to remember it between its own look and its own write gets the first's verdict, not a database error (issue
    32: "internal error" on a resumed process, seen in loops of the hang test). SQLite's statement trace puts the
    other run's check right before the first run's write."""
    store = tmp_path / "rb_00.ids.sqlite3"
    first = ReplayGuard(store, window=60, skew=5)
    other = ReplayGuard(store, window=60, skew=5)
    theirs: list[Verdict] = []

    def between(sql: str) -> None:  # the first run's write is about to run: the other run checks first
        if sql.startswith("INSERT") and "INTO seen" in sql and not theirs:
            theirs.append(other.check("cmd-1", "robot/x", now_text(), "d1"))

    first._db.set_trace_callback(between)
    try:
        assert first.check("cmd-1", "robot/x", now_text(), "d1") is Verdict.INHERITED
        assert theirs == [Verdict.NEW]
        first._db.set_trace_callback(None)
        assert other.check("cmd-1", "robot/x", now_text(), "d1") is Verdict.DUPLICATE  # still the other's
        assert first.check("cmd-1", "robot/y", now_text(), "d1") is Verdict.REUSED
    finally:
        first.close()
        other.close()
