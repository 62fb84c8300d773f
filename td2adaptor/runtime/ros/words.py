"""Failures in words a robot's user understands: what error and failure events say instead of class names.

An error event is read by an operator or an application, not by the edge node's developer: `PortCallFailed:
...` names a class of this project, `the robot call failed: ...` says what happened. The stable part for
programs is the event's `code` (or the feedback's `reason`); the message is for people.
"""

from __future__ import annotations

from td2adaptor.runtime.ros.port import NoValue, PortError, PortTimeout, PortUnavailable

INTERNAL = "internal error in the edge node (its log has the details)"

#: the ROS 1 master rospy uses when none is named (ROS_MASTER_URI unset)
DEFAULT_MASTER = "http://localhost:11311"


def master_silent(uri: str, why: str | OSError) -> str:
    """That the ROS 1 master at `uri` does not answer (`why`: the reason, or the error of the connection): which
    master, and how to name another. One wording for the ROS 1 bridge's start (bridge.py) and the ROS 1 graph's
    look (node/graphwatch.py), which said it each in their own words."""
    reason = why if isinstance(why, str) else why.strerror or str(why) or "no answer"
    return (
        f"the ROS 1 master {uri} does not answer ({reason}): is it running (roscore)? Name the one the robots use "
        "with --master-uri, the ros_master_uri setting or ROS_MASTER_URI"
    )


def describe(exc: BaseException) -> str:
    """What went wrong with a robot call, without internal class names."""
    text = str(exc).strip()
    if isinstance(exc, PortUnavailable):
        lead = "the robot is not reachable"
    elif isinstance(exc, PortTimeout):
        lead = "the robot did not answer in time"
    elif isinstance(exc, NoValue):
        lead = "the robot has published no value yet"
    elif isinstance(exc, PortError):
        lead = "the robot call failed"
    elif isinstance(exc, (TypeError, ValueError, KeyError)):  # building the request or reading the answer
        lead = "the edge node could not make the robot call"
    else:
        return INTERNAL
    return f"{lead}: {text}" if text else lead


def import_failure(package: str, exc: ImportError) -> str:
    """Why the generated adaptor package `package` cannot be imported, and how to make it importable (the words
    of `run` on ROS 2, and of the ROS 1 bridge's interpreter, which has its own path)."""
    missing = getattr(exc, "name", None) or package
    if isinstance(exc, ModuleNotFoundError) and (missing == package or package.startswith(missing + ".")):
        hint = (
            "build it and source the install space (colcon build; . install/setup.bash), or pass "
            "--package-path DIR with the generated package's source directory"
        )
        return f"cannot import the adaptor package {package!r}: {hint}"
    if isinstance(exc, ModuleNotFoundError):
        return (
            f"cannot import the adaptor package {package!r}: module {missing!r} is missing (build the interface "
            "packages and source their install space, or pass --prefix DIR for ROS 2 / --package-path DIR)"
        )
    return f"cannot import the adaptor package {package!r}: {exc}"


def setup_failure(exc: BaseException) -> str:
    """What went wrong while setting a robot's port up, without class names: the error's own words (the
    generated packages' errors say what and where), or that it said nothing."""
    return str(exc).strip() or "it failed without saying why (the log above may tell)"
