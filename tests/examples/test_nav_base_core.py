"""The nav_base's behaviour without middleware (examples/nav_base/sim/core.py), on a clock the test steps."""

from __future__ import annotations

import math

import pytest

from examples.nav_base.sim import core


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock() -> Clock:
    return Clock()


@pytest.fixture
def base(clock: Clock) -> core.BaseSim:
    return core.BaseSim("b", speed=2.0, dock_time=1.0, clock=clock)


def test_navigation_follows_the_clock(base: core.BaseSim, clock: Clock) -> None:
    task = base.navigate(4.0, 0.0, math.pi)
    assert task.seconds == 2.0 and not task.done
    clock.now += 1.0
    assert base.pose() == (2.0, 0.0, 0.0) and task.remaining() == 2.0 and task.time_left() == 1.0
    assert base.velocity() == (2.0, 0.0)
    clock.now += 1.0
    assert task.done and task.state == core.SUCCEEDED
    assert (base.x, base.y, base.theta) == (4.0, 0.0, math.pi) and base.velocity() == (0.0, 0.0)
    assert base.battery < 1.0


def test_refusals_say_why(base: core.BaseSim, clock: Clock) -> None:
    with pytest.raises(core.Refused, match=r"unreachable: \(50, 0\) is outside the map"):
        base.navigate(50.0, 0.0, 0.0)
    with pytest.raises(core.Refused, match="not a number"):
        base.navigate(math.nan, 0.0, 0.0)
    base.navigate(4.0, 0.0, 0.0)
    with pytest.raises(core.Refused, match="busy: navigate is running"):
        base.dock("cart2")
    clock.now += 2.0
    base.set_motors(False)
    with pytest.raises(core.Refused, match="the motors are off"):
        base.navigate(0.0, 0.0, 0.0)


def test_cancel_and_stop_leave_the_base_where_it_is(base: core.BaseSim, clock: Clock) -> None:
    task = base.navigate(4.0, 0.0, 0.0)
    clock.now += 0.5
    assert task.cancel() and task.state == core.CANCELED and task.message == "canceled"
    assert (base.x, base.y) == (1.0, 0.0) and not task.cancel()
    task = base.navigate(1.0, 2.0, 0.0)
    clock.now += 0.5
    assert base.stop() == (True, "stopped: navigate canceled")
    assert task.message == "stopped by the stop service" and (base.x, base.y) == (1.0, 1.0)
    assert base.stop() == (True, "stopped: nothing was running")


def test_docking_carries_the_cart(base: core.BaseSim, clock: Clock) -> None:
    far = base.dock("cart3")
    clock.now += 0.5
    assert far.done and far.state == core.FAILED and far.error_code == core.FAILED_TO_DETECT_DOCK
    unknown = base.dock("nope")
    clock.now += 0.5
    assert unknown.done and unknown.error_code == core.DOCK_NOT_IN_DB
    base.navigate(0.0, 3.0, 0.0)
    clock.now += 1.5
    docking = base.dock("cart2")
    clock.now += 1.0
    assert docking.done and docking.state == core.SUCCEEDED and base.carrying == "cart2"
    again = base.dock("cart2")
    clock.now += 0.5
    assert again.done and again.state == core.FAILED and again.error_code == core.DOCK_NOT_VALID
    base.navigate(8.0, -2.0, 0.0)
    clock.now += 10.0
    undock = base.undock()
    clock.now += 0.5
    assert undock.done and undock.state == core.SUCCEEDED
    assert base.carts["cart2"] == (8.0, -2.0) and base.carrying is None
    nothing = base.undock()
    assert nothing.done and nothing.state == core.FAILED and nothing.message == "not docked"


def test_cmd_vel_and_laser(base: core.BaseSim) -> None:
    assert base.drive(1.0, 0.0, 0.5) and (base.x, base.y) == (0.5, 0.0)
    ranges = base.laser()
    assert len(ranges) == core.LASER_BEAMS
    assert ranges[0] == pytest.approx(4.0) and ranges[90] == pytest.approx(9.5) and ranges[-1] == pytest.approx(5.0)
    assert base.drive(100.0, 0.0, 1.0) and base.x == 0.5  # would leave the map: stays
