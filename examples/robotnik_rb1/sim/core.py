"""The RB-1's procedure semantics, independent of any middleware (so ROS 1 and ROS 2 sims behave alike).

Each procedure component (GoTo, Pick, Place) runs one procedure at a time:
add → `queued` (last_event `added`) → `running` (`start`) after `queue_time` → `finished` (`finish`,
message "Perfect") after `duration`. An add while a procedure is queued or running is refused with the
robot's own message. Query and cancel take a mission id, -1 meaning the last one. A cancelled procedure
ends `finished` with last_event `cancel`. All times come from an injectable clock, so tests can step it.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

QUEUED, RUNNING, FINISHED, UNKNOWN = "queued", "running", "finished", "unknown"

#: where things are in the simulated warehouse (x, y); the marker id the robot sees when it stands there
DEFAULT_MARKERS: dict[int, tuple[float, float]] = {1: (5.0, 0.0), 2: (0.0, 3.0), 3: (1.5, 3.0), 4: (3.0, 3.0)}
SEE_RADIUS = 0.5


@dataclass
class Procedure:
    id: int
    component: str
    params: dict[str, Any]
    added: float
    state: str = QUEUED
    last_event: str = "added"
    result: str = "ok"
    message: str = ""
    ended: float | None = None


@dataclass
class ProcedureComponent:
    """One of GoToComponent / PickComponent / PlaceComponent."""

    name: str
    robot: RobotSim
    procedures: dict[int, Procedure] = field(default_factory=dict)
    last_id: int | None = None

    def _update(self, proc: Procedure, now: float) -> None:
        if proc.state == QUEUED and now >= proc.added + self.robot.queue_time:
            proc.state, proc.last_event = RUNNING, "start"
        if proc.state == RUNNING and now >= proc.added + self.robot.queue_time + self.robot.duration:
            proc.state, proc.last_event, proc.message = FINISHED, "finish", "Perfect"
            proc.ended = now
            self.robot.on_finished(self.name, proc)

    def active(self) -> Procedure | None:
        now = self.robot.clock()
        for proc in self.procedures.values():
            self._update(proc, now)
            if proc.state in (QUEUED, RUNNING):
                return proc
        return None

    def add(self, params: dict[str, Any]) -> dict[str, Any]:
        with self.robot.lock:
            busy = self.active()
            if busy is not None:
                return _reply(
                    -1 if self.last_id is None else self.last_id,
                    self.name,
                    UNKNOWN,
                    "abort",
                    "error",
                    f'Could not add procedure to "{self.name}" because component: "{self.name}" '
                    "is already running a procedure",
                )
            self.robot.next_id += 1
            proc = Procedure(self.robot.next_id, self.name, params, self.robot.clock())
            self.procedures[proc.id] = proc
            self.last_id = proc.id
            return _reply(proc.id, self.name, QUEUED, "added", "ok", "")

    def _find(self, mission_id: int) -> Procedure | None:
        key = self.last_id if mission_id == -1 else mission_id
        return self.procedures.get(key) if key is not None else None

    def query(self, mission_id: int) -> dict[str, Any]:
        with self.robot.lock:
            proc = self._find(mission_id)
            if proc is None:
                return _reply(mission_id, self.name, UNKNOWN, "abort", "error", f"no procedure with id {mission_id}")
            self._update(proc, self.robot.clock())
            return _reply(proc.id, self.name, proc.state, proc.last_event, proc.result, proc.message)

    def cancel(self, mission_id: int) -> dict[str, Any]:
        with self.robot.lock:
            proc = self._find(mission_id)
            if proc is None:
                return _reply(mission_id, self.name, UNKNOWN, "abort", "error", f"no procedure with id {mission_id}")
            self._update(proc, self.robot.clock())
            if proc.state in (QUEUED, RUNNING):
                proc.state, proc.last_event, proc.message = FINISHED, "cancel", "Cancelled"
                proc.ended = self.robot.clock()
            reply = _reply(proc.id, self.name, proc.state, proc.last_event, proc.result, proc.message)
            reply["last_message"] = proc.message
            return reply


def _reply(mid: int, name: str, state: str, event: str, result: str, message: str) -> dict[str, Any]:
    """The fields of a procedure response: state (with header) and result."""
    return {
        "state": {
            "header": {"id": mid, "priority": 0, "name": name},
            "current_state": state,
            "last_event": event,
        },
        "result": {"result": result, "message": message},
        "last_message": message,
    }


class RobotSim:
    """The whole robot: three procedure components, a pose, a cart lifter, markers and the door it commands."""

    def __init__(
        self,
        robot_id: str = "rb1_base_a",
        *,
        duration: float = 1.0,
        queue_time: float = 0.05,
        clock: Callable[[], float] = time.monotonic,
        markers: dict[int, tuple[float, float]] | None = None,
    ) -> None:
        self.robot_id = robot_id
        self.duration = duration
        self.queue_time = queue_time
        self.clock = clock
        self.lock = threading.RLock()
        self.next_id = 0
        self.x = self.y = self.theta = 0.0
        self.carrying: str | None = None
        self.markers = dict(DEFAULT_MARKERS if markers is None else markers)
        self.door_command: float | None = None
        self.components = {n: ProcedureComponent(n, self) for n in ("GoToComponent", "PickComponent", "PlaceComponent")}

    def on_finished(self, component: str, proc: Procedure) -> None:
        if component == "GoToComponent":
            goals = proc.params.get("goals") or []
            if goals:
                pose = goals[-1].get("pose", {})
                self.x, self.y, self.theta = (float(pose.get(k, 0.0)) for k in ("x", "y", "theta"))
        elif component == "PickComponent":
            self.carrying = str(proc.params.get("pick_frame_id", "")) or "cart"
        elif component == "PlaceComponent":
            self.carrying = None

    def operation_state(self) -> str:
        with self.lock:
            for name, state in (
                ("GoToComponent", "moving"),
                ("PickComponent", "raising_elevator"),
                ("PlaceComponent", "lowering_elevator"),
            ):
                if self.components[name].active() is not None:
                    return state
            return "idle"

    def status(self) -> dict[str, Any]:
        """The fields of robot_local_control_msgs/Status that the simulation fills."""
        with self.lock:
            op = self.operation_state()
            current = next((c.active() for c in self.components.values() if c.active() is not None), None)
            return {
                "robot_id": self.robot_id,
                "robot_state": "ready",
                "control_state": "auto",
                "operation_state": op,
                "mission_status": {
                    "current": {
                        "id": current.id if current else 0,
                        "description": current.component if current else "",
                        "state": current.state if current else "",
                    }
                },
                "pose": (self.x, self.y, self.theta),
                "carrying": self.carrying,
            }

    def visible_markers(self) -> list[int]:
        with self.lock:
            self.operation_state()  # advance procedures, so a finished goto moves the robot
            return sorted(
                mid for mid, (mx, my) in self.markers.items() if math.hypot(self.x - mx, self.y - my) <= SEE_RADIUS
            )

    def set_door(self, value: float) -> None:
        with self.lock:
            self.door_command = value
