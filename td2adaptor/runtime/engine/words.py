"""Failures in words a robot's user understands: what error and failure events say instead of class names.

An error event is read by an operator or an application, not by the edge node's developer: `PortCallFailed:
...` names a class of this project, `the robot call failed: ...` says what happened. The stable part for
programs is the event's `code` (or the feedback's `reason`); the message is for people.
"""

from __future__ import annotations

from td2adaptor.runtime.ros.port import NoValue, PortError, PortTimeout, PortUnavailable

INTERNAL = "internal error in the edge node (its log has the details)"


def describe(exc: BaseException) -> str:
    """What went wrong with a robot call, without internal class names."""
    text = str(exc).strip()
    if isinstance(exc, PortUnavailable):
        lead = "the robot is not reachable"
    elif isinstance(exc, PortTimeout):
        lead = "the robot did not answer in time"
    elif isinstance(exc, NoValue):
        lead = "the robot has published no value yet"
    elif isinstance(exc, (PortError, TypeError, ValueError, KeyError)):
        lead = "the robot call failed"
    else:
        return INTERNAL
    return f"{lead}: {text}" if text else lead
