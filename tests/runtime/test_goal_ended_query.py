"""A query or cancel of a ROS action goal that ended before the node's restart (or before the action's next goal)
is answered with the goal's end as the node's ledger recorded it (runtime/engine/goals.py `_recorded`, ledger.py
`ended_goal`), not refused `unsupported` (a new user's finding: "how did goal G end?" after a restart). Only a
goal id the node never had stays `unsupported`. In process, on the local bus and simulated action servers, with
the node stopped and started again on one state directory (test_goal_rejoin.py's `Node`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from td2adaptor.runtime.engine.ledger import Ledger
from tests.runtime.edge import Recorder, until
from tests.runtime.test_goal_rejoin import ROBOT, Node


def _ask(node: Node, errors: Recorder, suffix: str, correlation: str, goal: str | None) -> dict[str, Any]:
    """Send a query or cancel (`suffix`) for `goal`; its answer: a state event, or an error event."""

    def answers() -> list[dict[str, Any]]:
        seen = node.app.of("state") + errors.of("error")
        return [e for e in seen if e.get("correlation") == correlation]

    payload = {} if goal is None else {"goal": goal}
    node.send(suffix, {"id": correlation, "correlation": correlation, "payload": payload})
    assert until(lambda: bool(answers()), 20), (node.app.events[-3:], errors.events)
    return answers()[0]


def _as_ended(answer: dict[str, Any], end: dict[str, Any], goal: str) -> None:
    """The answer is a state event with the goal's end, as its terminal feedback said it."""
    assert answer["type"] == "state", answer
    payload = answer["payload"]
    assert payload["goal"] == goal and payload["terminal"] is True, payload
    for key in ("state", "result", "message", "reason"):
        assert payload.get(key) == end["payload"].get(key), (key, payload, end["payload"])


def test_a_goal_that_ended_in_the_last_run_is_answered_with_its_end_after_a_restart(tmp_path: Path) -> None:
    node = Node(tmp_path, step=0.02)
    errors = Recorder(node.broker, [f"td2adaptor/{ROBOT}/error"], "errors")
    try:
        node.start()
        node.send("", {"id": "g-1", "correlation": "g-1", "payload": {"order": 5}})
        first = node.ended("g-1")
        node.send("", {"id": "g-2", "correlation": "g-2", "payload": {"order": 400}})  # 8 s: cancelled below
        assert until(lambda: any(e["payload"]["state"] == "running" for e in node.feedback("g-2")), 20)
        node.send("/cancel", {"id": "c-0", "correlation": "c-0", "payload": {}})
        second = node.ended("g-2")
        assert second["payload"]["state"] == "cancelled", second
        one, two = first["payload"]["goal"], second["payload"]["goal"]
        # in this run, the goal before the action's last one
        _as_ended(_ask(node, errors, "/query", "q-0", one), first, one)
        node.stop()
        node.start()
        # after the restart: a query and a cancel by goal id, and a query of the action's last goal
        _as_ended(_ask(node, errors, "/query", "q-1", one), first, one)
        _as_ended(_ask(node, errors, "/cancel", "c-1", one), first, one)
        _as_ended(_ask(node, errors, "/query", "q-2", two), second, two)
        _as_ended(_ask(node, errors, "/cancel", "c-2", two), second, two)
        _as_ended(_ask(node, errors, "/query", "q-3", None), second, two)
        assert first["payload"]["state"] == "finished" and second["payload"]["result"] == "canceled"
        # a goal id this node never had stays unknown
        never = "0" * 32
        for suffix, correlation in (("/query", "q-4"), ("/cancel", "c-4")):
            refusal = _ask(node, errors, suffix, correlation, never)
            assert refusal["type"] == "error" and refusal["payload"]["code"] == "unsupported", refusal
            assert never in refusal["payload"]["message"], refusal
    finally:
        node.close()
        errors.close()


def test_the_ledger_keeps_an_ended_goal_for_its_retention_only() -> None:
    """`ended_goal` finds a goal once its terminal event is stored, by its id or as the action's latest, and no
    longer once its row is past `keep` (pruned or not: the answer must not depend on when the prune ran)."""
    now = [1000.0]
    ledger = Ledger(None, keep=30.0, clock=lambda: now[0])
    try:

        def goal(goal: str, state: str, terminal: bool) -> str:
            key = ledger.open(event_id=goal, topic="t", kind="goal", component="C", action="a", correlation=None)
            ledger.event(key, mission=None, goal=goal, state=state, seq=1, reserved=1, latest="{}", terminal=terminal)
            now[0] += 1
            return key

        done = goal("g1", "finished", True)
        ending = goal("g2", "cancelled", True)
        goal("g3", "running", False)  # in flight: not ended
        assert ledger.ended_goal("C", "a", "g3") is None
        assert ledger.ended_goal("C", "b", "g1") is None and ledger.ended_goal("D", "a", "g1") is None
        ledger.done(done)
        found = ledger.ended_goal("C", "a", "g1")
        assert found is not None and found.state == "finished"
        latest = ledger.ended_goal("C", "a", None)
        assert latest is not None and latest.goal == "g2"  # stored, maybe not sent yet: ended all the same
        now[0] += 20
        ledger.done(ending)
        now[0] += 11  # past g1's retention (30 s after its end), not g2's
        assert ledger.ended_goal("C", "a", "g1") is None
        assert ledger.ended_goal("C", "a", "g2") is not None
    finally:
        ledger.close()
