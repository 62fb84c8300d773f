"""Reading a robot's procedure responses as one of six procedure states.

By default the procedures_msgs convention (`interpret`); a binding may name the state field and map its
values instead (`read`). The reference edge node mapped `finished` with `last_event == abort` to `unknown`
and everything unexpected to `unknown`; we keep the distinction instead: finished, failed (with a reason)
or cancelled.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from td2adaptor.model import Procedure
from td2adaptor.model.events import TERMINAL_STATES


@dataclass(frozen=True)
class ProcedureStatus:
    state: str  # queued, running, paused, finished, failed, cancelled
    result: str = ""
    message: str = ""
    last_event: str = ""
    reason: str | None = None  # set when state == failed
    mission_id: int | None = None

    @property
    def terminal(self) -> bool:
        return self.state in TERMINAL_STATES

    def payload(self) -> dict[str, Any]:
        """The fields of a feedback/state payload (without seq and terminal)."""
        out: dict[str, Any] = {"state": self.state}
        if self.result:
            out["result"] = self.result
        if self.message:
            out["message"] = self.message
        if self.last_event:
            out["last_event"] = self.last_event
        if self.reason:
            out["reason"] = self.reason
        return out


def _get(data: Any, *path: str) -> Any:
    for key in path:
        if not isinstance(data, Mapping):
            return None
        data = data.get(key)
    return data


def _text(value: Any) -> str:
    if isinstance(value, Mapping):  # std_msgs/String
        value = value.get("data", "")
    return value if isinstance(value, str) else ""


def mission_id_of(response: Mapping[str, Any], path: Sequence[str]) -> int | None:
    value = _get(response, *path) if path else None
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def interpret(response: Any, mission_path: Sequence[str] = ("state", "header", "id")) -> ProcedureStatus:
    """A procedure response (state/current_state, state/last_event, result/result, result/message)."""
    if not isinstance(response, Mapping):
        return ProcedureStatus("failed", message="no response from the robot", reason="unreachable")
    current = str(_get(response, "state", "current_state") or "").lower()
    last_event = str(_get(response, "state", "last_event") or "").lower()
    result = str(_get(response, "result", "result") or "")
    message = _text(_get(response, "result", "message")) or _text(response.get("last_message"))
    mission = mission_id_of(response, mission_path)
    if current in ("queued", "running", "paused"):
        state, reason = current, None
    elif current == "finished" and last_event == "cancel":
        state, reason = "cancelled", None
    elif current in ("cancelled", "canceled"):
        state, reason = "cancelled", None
    elif current == "finished" and last_event == "abort":
        state, reason = "failed", "aborted"
    elif current == "finished" and result.lower() == "error":
        state, reason = "failed", "robot-error"
    elif current == "finished":
        state, reason = "finished", None
    elif current in ("error", "failed", "aborted"):
        state, reason = "failed", "robot-error"
    else:  # unknown, empty or something new: the robot does not know this procedure (or refused it)
        state, reason = "failed", "robot-error"
    return ProcedureStatus(state, result, message, last_event, reason, mission)


@dataclass(frozen=True)
class Reading:
    """What one response says: `status` (None when this kind of response carries no state: the call was
    taken, nothing more), or the `unmapped` value of a mapped state field no state is given for."""

    status: ProcedureStatus | None
    unmapped: str | None = None


def _value_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return value if isinstance(value, str) else str(value)


def read(response: Any, procedure: Procedure, role: str, default_path: Sequence[str] = ()) -> Reading:
    """The state in a `role` ("run", "query", "cancel") response of `procedure` (see `Procedure`)."""
    if role not in procedure.stateful:
        return Reading(None)
    path = procedure.mission_id or tuple(default_path)
    if not procedure.state:
        return Reading(interpret(response, path))
    if not isinstance(response, Mapping):
        return Reading(ProcedureStatus("failed", message="no response from the robot", reason="unreachable"))
    text = _value_text(_get(response, *procedure.state))
    state = dict(procedure.states).get(text)
    message = _text(_get(response, *procedure.message)) if procedure.message else ""
    if state is None:
        return Reading(None, unmapped=text)
    reason = "robot-error" if state == "failed" else None
    return Reading(ProcedureStatus(state, text, message, reason=reason, mission_id=mission_id_of(response, path)))
