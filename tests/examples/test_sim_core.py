"""The simulated RB-1's procedure semantics (the middleware adapters are tested with real ROS)."""

from __future__ import annotations

from examples.robotnik_rb1.sim.core import RobotSim


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_add_queue_run_finish_and_busy_refusal() -> None:
    clock = Clock()
    robot = RobotSim(duration=2.0, queue_time=0.5, clock=clock)
    goto = robot.components["GoToComponent"]
    reply = goto.add({"goals": [{"pose": {"x": 1.5, "y": 3.0, "theta": 0.0}}]})
    mid = reply["state"]["header"]["id"]
    assert (reply["state"]["current_state"], reply["state"]["last_event"], reply["result"]["result"]) == (
        "queued",
        "added",
        "ok",
    )
    busy = goto.add({})
    assert busy["state"]["current_state"] == "unknown" and busy["result"]["result"] == "error"
    assert busy["result"]["message"] == (
        'Could not add procedure to "GoToComponent" because component: "GoToComponent" is already running a procedure'
    )
    clock.now += 1.0
    assert goto.query(mid)["state"]["current_state"] == "running"
    assert robot.operation_state() == "moving"
    clock.now += 2.0
    done = goto.query(-1)
    assert (done["state"]["current_state"], done["state"]["last_event"], done["result"]["message"]) == (
        "finished",
        "finish",
        "Perfect",
    )
    assert robot.operation_state() == "idle"
    assert robot.visible_markers() == [3]  # standing at cart 3


def test_cancel_by_id_and_unknown_id() -> None:
    clock = Clock()
    robot = RobotSim(duration=5.0, clock=clock)
    pick = robot.components["PickComponent"]
    mid = pick.add({"pick_frame_id": "rb1_base_a_cart2_contact"})["state"]["header"]["id"]
    clock.now += 1.0
    cancelled = pick.cancel(mid)
    assert (cancelled["state"]["current_state"], cancelled["state"]["last_event"]) == ("finished", "cancel")
    assert pick.query(mid)["state"]["last_event"] == "cancel"
    assert pick.query(999)["result"]["result"] == "error"
    assert robot.carrying is None  # a cancelled pick lifts nothing
    # ids are unique across components
    other = robot.components["PlaceComponent"].add({})["state"]["header"]["id"]
    assert other == mid + 1
