"""What the engine's mission runners share of one robot, in one object: built once by the engine as it starts.

`ProcedureRunner` (procedure.py) and `GoalRunner` (goals.py) follow a robot's missions with the same
collaborators: the robot's port, its settings, its `MissionTable` and `Outbox`, the process's loop, the robot's
lane of the call pool, the flag that says the engine stops, and the clock. Handing them this rather than the
`Engine` keeps the runners from reaching into it; handing it rather than eight arguments keeps the two alike.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

from td2adaptor.model.events import Kind
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.missions import MissionTable
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.loop import Lane, Loop
from td2adaptor.runtime.ros.port import QuickCall, RobotPort


@dataclass(frozen=True)
class RobotContext:
    """One robot's collaborators (see the module docstring)."""

    port: RobotPort
    config: RuntimeConfig
    missions: MissionTable
    outbox: Outbox
    loop: Loop
    lane: Lane
    stopping: threading.Event
    clock: Callable[[], float]
    #: before a ROS action goal is sent: `gate(go)` calls `go(True)` once it may be, `go(False)` if it must not
    #: (Engine.gate; None: at once)
    gate: Callable[[Callable[[bool], None]], None] | None = None
    #: the port, when it can make calls without a waiting thread (`QuickCall`: ROS 2's generated packages)
    quick: QuickCall | None = None

    def topic(self, kind: Kind, affordance: str, component: str | None = None) -> str:
        """The topic of the robot's `kind` event of `affordance` ("" when the robot has none)."""
        for spec in self.outbox.catalog.specs:
            if (
                spec.kind is kind
                and spec.affordance == affordance
                and (component is None or spec.component == component)
            ):
                return spec.topic(self.config.robot, self.config.topic_root)
        return ""
