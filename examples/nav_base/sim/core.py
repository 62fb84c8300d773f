"""The nav_base's behaviour, independent of any middleware (so the ROS 1 and ROS 2 simulations act alike).

A base on a flat rectangular map (`Map`) that drives straight to a goal at `speed` m/s, turning on the
spot at no cost. Positions follow from the clock (never from how often someone looks), so a goal takes
distance/speed seconds however loaded the machine is. One task at a time:

* `navigate(x, y, theta)` → a `Task`, or `Refused` with the robot's words: busy with another task, the
  pose outside the map (unreachable), the motors off;
* `dock(dock_id)` under a cart standing within `DOCK_RADIUS` of the base: unknown id → DOCK_NOT_IN_DB,
  too far → FAILED_TO_DETECT_DOCK, already carrying one → DOCK_NOT_VALID (the task ends failed, as Nav2's
  docking server aborts); it takes `dock_time` and the base then carries the cart;
* `undock()` leaves the cart where the base stands (`dock_time/2`);
* `Task.cancel()` stops where the base is; `stop()` cancels whatever runs. A carried cart moves with the base.

Odometry, battery (drains with distance) and a laser scan (ranges to the map's walls) are computed on demand.
All times come from an injectable clock, so tests can step it.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

#: the carts (dock ids) and where they stand; the warehouse demo's picking points
DEFAULT_CARTS: dict[str, tuple[float, float]] = {"cart2": (0.0, 3.0), "cart3": (1.5, 3.0), "cart4": (3.0, 3.0)}
DOCK_RADIUS = 0.5
LASER_BEAMS = 181
LASER_MAX = 30.0

# result codes (the constants of nav_base_msgs' actions)
NAV_NONE, NAV_UNKNOWN = 0, 9000
DOCK_NONE, DOCK_NOT_IN_DB, DOCK_NOT_VALID, FAILED_TO_DETECT_DOCK = 0, 901, 902, 904
# DockRobot feedback states
DOCK_INITIAL_PERCEPTION, DOCK_CONTROLLING = 2, 3

NAVIGATE, DOCK, UNDOCK = "navigate", "dock", "undock"
RUNNING, SUCCEEDED, FAILED, CANCELED = "running", "succeeded", "failed", "canceled"


class Refused(Exception):
    """The robot will not start this task (a rejected goal); the message is the robot's words."""


@dataclass(frozen=True)
class Map:
    """The free rectangle the base may drive in (metres, map frame)."""

    min_x: float = -2.0
    min_y: float = -4.0
    max_x: float = 10.0
    max_y: float = 5.0

    def contains(self, x: float, y: float) -> bool:
        return self.min_x <= x <= self.max_x and self.min_y <= y <= self.max_y

    def range_to_wall(self, x: float, y: float, angle: float) -> float:
        """Distance from (x, y) along `angle` to the rectangle's border (the walls the laser sees)."""
        dx, dy = math.cos(angle), math.sin(angle)
        hits = []
        if dx > 1e-9:
            hits.append((self.max_x - x) / dx)
        elif dx < -1e-9:
            hits.append((self.min_x - x) / dx)
        if dy > 1e-9:
            hits.append((self.max_y - y) / dy)
        elif dy < -1e-9:
            hits.append((self.min_y - y) / dy)
        return max(0.0, min(hits)) if hits else LASER_MAX


@dataclass
class Task:
    """One running (or ended) task of the base: a navigation, a docking or an undocking."""

    kind: str
    base: BaseSim
    started: float
    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    seconds: float
    dock_id: str = ""
    state: str = RUNNING
    error_code: int = 0
    message: str = ""
    ended: float | None = None
    fail_at: float | None = None  # a docking that fails does so half-way

    def update(self) -> None:
        """Advance to the clock's time (under the base's lock)."""
        if self.state != RUNNING:
            return
        now = self.base.clock()
        if self.fail_at is not None and now >= self.started + self.fail_at:
            self._end(FAILED, now)
        elif now >= self.started + self.seconds:
            self.base._finish(self)
            self._end(SUCCEEDED, now)

    def _end(self, state: str, now: float) -> None:
        self.state, self.ended = state, now
        if self.base.task is self:
            self.base.task = None

    @property
    def done(self) -> bool:
        with self.base.lock:
            self.update()
            return self.state != RUNNING

    def progress(self) -> float:
        """0..1 of the way."""
        if self.seconds <= 0:
            return 1.0
        end = self.ended if self.ended is not None else self.base.clock()
        return min(1.0, max(0.0, (end - self.started) / self.seconds))

    def elapsed(self) -> float:
        """Seconds the task has run (at most its planned time, however late someone asks)."""
        end = self.ended if self.ended is not None else self.base.clock()
        return min(self.seconds, max(0.0, end - self.started))

    def pose(self) -> tuple[float, float, float]:
        """Where the base is on this task's way (the start for docking and undocking, which do not move it)."""
        if self.kind != NAVIGATE:
            return self.start
        p = self.progress()
        (x0, y0, t0), (x1, y1, t1) = self.start, self.goal
        theta = t1 if p >= 1.0 else math.atan2(y1 - y0, x1 - x0) if (x1, y1) != (x0, y0) else t0
        return (x0 + (x1 - x0) * p, y0 + (y1 - y0) * p, theta)

    def remaining(self) -> float:
        """Metres left to drive (navigation), 0 otherwise."""
        if self.kind != NAVIGATE:
            return 0.0
        x, y, _ = self.pose()
        return math.hypot(self.goal[0] - x, self.goal[1] - y)

    def time_left(self) -> float:
        return max(0.0, self.seconds - self.elapsed())

    def cancel(self, why: str = "canceled") -> bool:
        """Stop here, saying `why`; whether the task was still running."""
        with self.base.lock:
            self.update()
            if self.state != RUNNING:
                return False
            if self.kind == NAVIGATE:
                self.base.x, self.base.y, self.base.theta = self.pose()
            self.message = why
            self._end(CANCELED, self.base.clock())
            return True


@dataclass
class BaseSim:
    """The whole base: its pose, motors, battery, the cart it carries and the carts of the warehouse."""

    name: str = "nav_base_a"
    speed: float = 1.0
    dock_time: float = 0.5
    clock: Callable[[], float] = time.monotonic
    world: Map = field(default_factory=Map)
    carts: dict[str, tuple[float, float]] = field(default_factory=lambda: dict(DEFAULT_CARTS))
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    motors: bool = True
    battery: float = 1.0  # fraction of charge
    carrying: str | None = None
    task: Task | None = None
    driven: float = 0.0  # metres, for the battery
    lock: threading.RLock = field(default_factory=threading.RLock)

    # -- tasks -------------------------------------------------------------------------------------------

    def _busy(self) -> str | None:
        if self.task is not None:
            self.task.update()
        if self.task is not None:
            return f"busy: {self.task.kind} is running"
        if not self.motors:
            return "the motors are off"
        return None

    def _start(self, kind: str, goal: tuple[float, float, float], seconds: float, dock_id: str = "") -> Task:
        task = Task(kind, self, self.clock(), (self.x, self.y, self.theta), goal, seconds, dock_id)
        self.task = task
        return task

    def navigate(self, x: float, y: float, theta: float) -> Task:
        """Start driving to (x, y, theta); Refused when busy, outside the map or with the motors off."""
        with self.lock:
            why = self._busy()
            if why is None and not all(math.isfinite(v) for v in (x, y, theta)):
                why = "unreachable: the goal pose is not a number"
            if why is None and not self.world.contains(x, y):
                w = self.world
                bounds = f"x {w.min_x:g}..{w.max_x:g}, y {w.min_y:g}..{w.max_y:g}"
                why = f"unreachable: ({x:g}, {y:g}) is outside the map ({bounds})"
            if why is not None:
                raise Refused(why)
            distance = math.hypot(x - self.x, y - self.y)
            return self._start(NAVIGATE, (x, y, theta), distance / self.speed)

    def dock(self, dock_id: str) -> Task:
        """Start docking under cart `dock_id`; a docking that cannot succeed fails half-way with a code."""
        with self.lock:
            why = self._busy()
            if why is not None:
                raise Refused(why)
            task = self._start(DOCK, (self.x, self.y, self.theta), self.dock_time, dock_id)
            if self.carrying is not None:
                task.error_code, task.message = DOCK_NOT_VALID, f"already docked to {self.carrying}"
            elif dock_id not in self.carts:
                task.error_code, task.message = DOCK_NOT_IN_DB, f"no dock {dock_id!r} in the database"
            elif math.hypot(self.carts[dock_id][0] - self.x, self.carts[dock_id][1] - self.y) > DOCK_RADIUS:
                cx, cy = self.carts[dock_id]
                task.error_code = FAILED_TO_DETECT_DOCK
                here = f"({self.x:g}, {self.y:g})"
                task.message = f"{dock_id} not detected: it stands at ({cx:g}, {cy:g}), the base at {here}"
            if task.error_code:
                task.fail_at = self.dock_time / 2
            return task

    def undock(self) -> Task:
        with self.lock:
            why = self._busy()
            if why is not None:
                raise Refused(why)
            task = self._start(UNDOCK, (self.x, self.y, self.theta), self.dock_time / 2)
            if self.carrying is None:
                task.error_code, task.message, task.fail_at = DOCK_NOT_VALID, "not docked", 0.0
            return task

    def _finish(self, task: Task) -> None:
        """A task reached its end: apply it to the base (under the lock)."""
        if task.kind == NAVIGATE:
            self.driven += math.hypot(task.goal[0] - task.start[0], task.goal[1] - task.start[1])
            self.battery = max(0.05, 1.0 - 0.002 * self.driven)
            self.x, self.y, self.theta = task.goal
            if self.carrying is not None:
                self.carts[self.carrying] = (self.x, self.y)
        elif task.kind == DOCK:
            self.carrying = task.dock_id
            task.message = f"docked to {task.dock_id}"
        elif task.kind == UNDOCK:
            task.message = f"left {self.carrying} at ({self.x:g}, {self.y:g})"
            self.carts[str(self.carrying)] = (self.x, self.y)
            self.carrying = None

    def stop(self) -> tuple[bool, str]:
        """Cancel whatever runs (the Trigger service's answer: success, message)."""
        with self.lock:
            task = self.task
            if task is not None and task.cancel("stopped by the stop service"):
                return True, f"stopped: {task.kind} canceled"
            return True, "stopped: nothing was running"

    def set_motors(self, on: bool) -> tuple[bool, str]:
        """SetBool: motors off cancels the running task."""
        with self.lock:
            if not on and self.task is not None:
                self.task.cancel("stopped: the motors were switched off")
            self.motors = on
            return True, "motors on" if on else "motors off"

    def drive(self, linear: float, angular: float, seconds: float) -> bool:
        """A velocity command held for `seconds` (cmd_vel): moves the base when idle with motors on, staying
        inside the map; whether it moved."""
        with self.lock:
            if self._busy() is not None:
                return False
            self.theta = math.remainder(self.theta + angular * seconds, math.tau)
            nx = self.x + math.cos(self.theta) * linear * seconds
            ny = self.y + math.sin(self.theta) * linear * seconds
            if self.world.contains(nx, ny):
                self.driven += math.hypot(nx - self.x, ny - self.y)
                self.x, self.y = nx, ny
            return True

    # -- what the sensors say ------------------------------------------------------------------------------

    def pose(self) -> tuple[float, float, float]:
        with self.lock:
            if self.task is not None:
                self.task.update()
            if self.task is not None:
                return self.task.pose()
            return (self.x, self.y, self.theta)

    def velocity(self) -> tuple[float, float]:
        """(linear, angular) now: the cruise speed while navigating, else 0."""
        with self.lock:
            if self.task is not None:
                self.task.update()
            moving = self.task is not None and self.task.kind == NAVIGATE and self.task.remaining() > 0
            return (self.speed if moving else 0.0, 0.0)

    def laser(self) -> list[float]:
        """Ranges of LASER_BEAMS beams from -90° to +90° around the heading, to the walls."""
        x, y, theta = self.pose()
        step = math.pi / (LASER_BEAMS - 1)
        return [
            min(LASER_MAX, self.world.range_to_wall(x, y, theta - math.pi / 2 + i * step)) for i in range(LASER_BEAMS)
        ]


def yaw_of(z: float, w: float) -> float:
    """Heading of a quaternion that only turns about z."""
    return 2.0 * math.atan2(z, w)


def quaternion_z_w(theta: float) -> tuple[float, float]:
    return math.sin(theta / 2.0), math.cos(theta / 2.0)
