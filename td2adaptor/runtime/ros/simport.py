"""A `RobotPort` onto the middleware-independent simulated robot (`examples/robotnik_rb1/sim/core.py`).

For tests, benchmarks and the in-process demo: the same procedure semantics as the ROS simulations, without
ROS. It also shows what an adapter does: pick the component, turn the payload into the call's arguments,
turn the answer into plain data, and raise `PortError` subclasses. `down` and `delay` inject faults.
`SimActions` simulates ROS action servers (a Fibonacci-like goal: `order` feedback messages, then the
result) for every `SimPort` given it, telling each goal's events through the port's callback protocol
(`GoalListener`) from one thread of its own, whatever the number of goals, as the ROS client libraries do.
"""

from __future__ import annotations

import heapq
import itertools
import threading
import time
import uuid
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from td2adaptor.model import Model
from td2adaptor.model.events import payload_schema
from td2adaptor.model.msgschema import fill
from td2adaptor.runtime.ros.port import (
    CancelDone,
    GoalEnd,
    GoalListener,
    NoValue,
    PortCallFailed,
    PortRejected,
    PortUnavailable,
    StartResult,
)
from td2adaptor.runtime.ros.procedures import mission_id_of


class SimComponent(Protocol):
    def add(self, params: dict[str, Any]) -> dict[str, Any]: ...
    def query(self, mission_id: int) -> dict[str, Any]: ...
    def cancel(self, mission_id: int) -> dict[str, Any]: ...


class SimRobot(Protocol):
    """What `examples/robotnik_rb1/sim/core.RobotSim` offers."""

    robot_id: str

    @property
    def components(self) -> Mapping[str, SimComponent]: ...

    def status(self) -> dict[str, Any]: ...
    def visible_markers(self) -> list[int]: ...
    def set_door(self, value: float) -> None: ...


def rb1_readers(sim: SimRobot) -> dict[str, Callable[[], Any]]:
    """The RB-1's subscribed properties, in the shape of their ROS messages (the fields the sim knows)."""

    def availability() -> Any:
        status = sim.status()
        x, y, theta = status["pose"]
        return {
            "robot_id": status["robot_id"],
            "robot_state": status["robot_state"],
            "control_state": status["control_state"],
            "operation_state": status["operation_state"],
            "mission_status": {"current": status["mission_status"]["current"]},
            "robot_status": {"pose": {"pose": {"x": x, "y": y, "theta": theta}}},
        }

    def pose_marker() -> Any:
        return {"markers": [{"id": marker} for marker in sim.visible_markers()]}

    return {"availability": availability, "poseMarker": pose_marker}


def rb1_writers(sim: SimRobot) -> dict[str, Callable[[Any], None]]:
    def door(value: Any) -> None:
        data = value.get("data") if isinstance(value, Mapping) else None
        if not isinstance(data, (int, float)) or isinstance(data, bool):
            raise PortCallFailed("door: expected {'data': <number>}")
        sim.set_door(float(data))

    return {"door": door}


def _as_ros(response: dict[str, Any]) -> dict[str, Any]:
    """The sim's answer as the ROS response dict (std_msgs/String last_message)."""
    out = dict(response)
    if isinstance(out.get("last_message"), str):
        out["last_message"] = {"data": out["last_message"]}
    return out


def fibonacci(count: int) -> list[int]:
    """The first `count + 1` Fibonacci numbers (at least [0, 1])."""
    seq = [0, 1]
    while len(seq) < count + 1:
        seq.append(seq[-1] + seq[-2])
    return seq[: max(count + 1, 2)]


#: how many ended goals a simulated server keeps the end of (for a follower by id: `SimActions.rejoin`)
ENDS_KEPT = 100


class _SimGoal:
    def __init__(self, listener: GoalListener, order: int) -> None:
        self.listener = listener
        self.order = order
        self.sent = 0
        self.cancel = False
        self.over = False


class SimActions:
    """Simulated ROS action servers (see the module docstring): a goal of `{"order": n}` is accepted (n < 0:
    rejected), sends n feedback messages `{"sequence": [...]}` `step` seconds apart (40 at most are grown),
    then succeeds with `{"sequence": [...]}`; a cancel request ends it canceled at its next step. One daemon
    thread (`sim-actions`) keeps every goal's time."""

    def __init__(self, step: float = 0.05) -> None:
        self.step = step
        self._cond = threading.Condition()
        self._due: list[tuple[float, int, Callable[[], None]]] = []
        self._order = itertools.count()
        self._goals: dict[str, _SimGoal] = {}
        self._ended: dict[str, GoalEnd] = {}  # the last ENDS_KEPT ends, by goal (a ROS 2 server keeps results too)
        self.thread = threading.Thread(target=self._run, name="sim-actions", daemon=True)
        self.thread.start()

    def _later(self, delay: float, fn: Callable[[], None]) -> None:
        with self._cond:
            heapq.heappush(self._due, (time.monotonic() + delay, next(self._order), fn))
            self._cond.notify()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._due or self._due[0][0] > time.monotonic():
                    self._cond.wait(self._due[0][0] - time.monotonic() if self._due else None)
                _, _, fn = heapq.heappop(self._due)
            fn()

    def start(self, payload: Mapping[str, Any], listener: GoalListener) -> str:
        order = payload.get("order")
        if not isinstance(order, int) or isinstance(order, bool):
            raise PortCallFailed("the goal needs an integer `order`")
        goal = uuid.uuid4().hex
        state = _SimGoal(listener, order)
        with self._cond:
            self._goals[goal] = state
        self._later(0.0, lambda: self._answer(goal, state))
        return goal

    def _answer(self, goal: str, state: _SimGoal) -> None:
        if state.order < 0:
            self._end(goal, state, GoalEnd("rejected", error=PortRejected("the order must not be negative")))
            return
        state.listener.on_accepted(goal)
        state.listener.on_status("executing")
        self._later(self.step, lambda: self._next(goal, state))

    def _next(self, goal: str, state: _SimGoal) -> None:
        if state.over:
            return
        if state.cancel:
            self._end(goal, state, GoalEnd("canceled", {"sequence": fibonacci(min(state.sent, 40))}))
            return
        if state.sent >= state.order:
            self._end(goal, state, GoalEnd("succeeded", {"sequence": fibonacci(min(state.order, 40))}))
            return
        state.sent += 1
        state.listener.on_feedback({"sequence": fibonacci(min(state.sent, 40))})
        self._later(self.step, lambda: self._next(goal, state))

    def _end(self, goal: str, state: _SimGoal, end: GoalEnd) -> None:
        state.over = True
        with self._cond:
            self._goals.pop(goal, None)
            self._ended[goal] = end
            while len(self._ended) > ENDS_KEPT:
                del self._ended[next(iter(self._ended))]
        state.listener.on_done(end)

    def rejoin(self, goal: str, listener: GoalListener) -> None:
        """Follow a goal started through another listener (a node before its restart) from now on, in the
        servers' thread (between two of its steps): its end, if it ended and is still kept; lost when the server
        does not know it."""

        def follow() -> None:
            with self._cond:
                state = self._goals.get(goal)
                end = self._ended.get(goal)
                if state is not None:
                    state.listener = listener
            if state is not None:
                listener.on_accepted(goal)
                listener.on_status("executing")
            elif end is not None:
                listener.on_accepted(goal)
                listener.on_done(end)
            else:
                error = PortCallFailed(f"the action server does not know goal {goal}")
                listener.on_done(GoalEnd("lost", message=str(error), error=error))

        self._later(0.0, follow)

    def cancel(self, goal: str, on_done: CancelDone) -> None:
        with self._cond:
            state = self._goals.get(goal)
        if state is None:
            self._later(0.0, lambda: on_done(False, None))
            return
        self._later(0.0, lambda: self._canceling(state, on_done))

    @staticmethod
    def _canceling(state: _SimGoal, on_done: CancelDone) -> None:
        if state.over:  # ended meanwhile: nothing to cancel
            on_done(False, None)
            return
        state.cancel = True
        state.listener.on_status("canceling")
        on_done(True, None)


class SimPort:
    """Drives a simulated robot through the `RobotPort` protocol (and its ROS actions through `actions`)."""

    def __init__(
        self,
        model: Model,
        sim: SimRobot,
        *,
        readers: Mapping[str, Callable[[], Any]] | None = None,
        writers: Mapping[str, Callable[[Any], None]] | None = None,
        request_field: str = "procedure",
        actions: SimActions | None = None,
    ) -> None:
        self.model = model
        self.sim = sim
        self.actions = actions
        self.readers = dict(rb1_readers(sim) if readers is None else readers)
        self.writers = dict(rb1_writers(sim) if writers is None else writers)
        self.request_field = request_field
        # what the sim knows of a message, completed as ROS would send it: every field, defaults where unset
        self._schemas = {
            t.name: payload_schema(model, t.type_name, t.schema, distro="ros2", complete=True)
            for c in model.components
            for t in c.topics
        }
        self.down = False  # fault injection: every call fails as if the robot were gone
        self.watched = False  # tests: the edge node watches `down` as the robot's presence (node/presence.py)
        self.delay = 0.0  # fault injection: seconds each call takes
        self.calls: list[tuple[str, str]] = []  # (component, action) in call order
        self._lock = threading.Lock()

    def _enter(self, component: str, action: str, timeout: float) -> SimComponent:
        with self._lock:
            self.calls.append((component, action))
        if self.down:
            raise PortUnavailable(f"service {action} of {component} is not available")
        if self.delay:
            if self.delay > timeout:
                time.sleep(timeout)
                raise PortUnavailable(f"{action} did not answer within {timeout:g} s")
            time.sleep(self.delay)
        try:
            return self.sim.components[component]
        except KeyError:
            raise PortCallFailed(f"the robot has no component {component!r}") from None

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> StartResult:
        comp = self._enter(component, action, timeout)
        params = payload.get(self.request_field, payload)
        if not isinstance(params, Mapping):
            raise PortCallFailed(f"{action}: {self.request_field} must be an object")
        response = _as_ros(comp.add(dict(params)))
        procedure = self.model.component(component).procedure_of(action)
        path = procedure.mission_id if procedure is not None and procedure.mission_id else ("state", "header", "id")
        return StartResult(response, mission_id_of(response, path))

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        return _as_ros(self._enter(component, action, timeout).query(mission_id))

    def cancel(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        return _as_ros(self._enter(component, action, timeout).cancel(mission_id))

    def call(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Mapping[str, Any]:
        self._enter(component, action, timeout)
        raise PortCallFailed(f"the simulation has no plain action {action!r}")

    def read_property(self, component: str, name: str, timeout: float) -> Any:
        if self.down:
            raise PortUnavailable(f"topic of {name} is silent")
        reader = self.readers.get(name)
        if reader is None:
            raise NoValue(f"no message on {name} yet")
        schema = self._schemas.get(name)
        return reader() if schema is None else fill(schema, reader())

    def write_property(self, component: str, name: str, value: Any) -> None:
        if self.down:
            raise PortUnavailable(f"publisher of {name} is gone")
        writer = self.writers.get(name)
        if writer is None:
            raise PortCallFailed(f"the simulation does not publish {name!r}")
        writer(value)

    # -- ROS actions (the `GoalPort` protocol): the simulated servers of `actions`

    def start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str:
        with self._lock:
            self.calls.append((component, action))
        if self.actions is None:
            raise PortCallFailed("the simulation has no ROS actions")
        if self.down:
            raise PortUnavailable(f"the action server of {action} is not available")
        return self.actions.start(payload, listener)

    def try_start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str | None:
        """`start_goal`, which never waits here (`QuickGoalStart`)."""
        return self.start_goal(component, action, payload, timeout, listener)

    def rejoin_goal(self, component: str, action: str, goal: str, timeout: float, listener: GoalListener) -> None:
        """Follow a goal the simulated servers have by its id (`GoalRejoin`)."""
        if self.actions is None:
            raise PortCallFailed("the simulation has no ROS actions")
        if self.down:
            raise PortUnavailable(f"the action server of {action} is not available")
        self.actions.rejoin(goal, listener)

    def request_cancel(self, component: str, action: str, goal: str, timeout: float, on_done: CancelDone) -> None:
        if self.actions is None:
            on_done(False, PortCallFailed("the simulation has no ROS actions"))
            return
        self.actions.cancel(goal, on_done)

    def forget_goal(self, component: str, action: str, goal: str) -> None:
        """Nothing to forget: a simulated goal tells its listener until it ends."""
