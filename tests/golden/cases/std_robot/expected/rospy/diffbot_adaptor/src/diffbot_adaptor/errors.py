"""Errors raised by the diffbot_adaptor adaptor: one base class, so callers can catch everything at once."""

from __future__ import annotations

from typing import Any


class AdaptorError(Exception):
    """Base class of every error this adaptor raises on purpose."""


class InvalidRobotName(AdaptorError, ValueError):
    """The robot name given to a component is not a valid ROS namespace."""


class NotInitialized(AdaptorError, RuntimeError):
    """rospy.init_node() has not been called in this process yet."""


class InvalidMessage(AdaptorError, TypeError):
    """A message could not be built from the given values (unknown field or wrong kind of value)."""


class ServiceUnavailable(AdaptorError):
    """The robot's service could not be reached (not advertised, or the connection could not be made)."""

    def __init__(self, service: str, message: str) -> None:
        super().__init__(f"{service}: {message}")
        self.service = service
        self.message = message


class CallTimeout(AdaptorError):
    """The robot did not answer a service call within the timeout."""

    def __init__(self, service: str, timeout: float) -> None:
        super().__init__(f"{service}: no answer within {timeout:g} s")
        self.service = service
        self.timeout = timeout


class CallFailed(AdaptorError):
    """The call reached the robot, but it failed; `message` is the robot's own explanation."""

    def __init__(self, service: str, message: str, response: Any = None) -> None:
        super().__init__(f"{service}: {message}")
        self.service = service
        self.message = message
        self.response = response


class NoMessage(AdaptorError):
    """No message arrived on a topic within the timeout."""

    def __init__(self, topic: str, timeout: float) -> None:
        super().__init__(f"{topic}: no message within {timeout:g} s")
        self.topic = topic
        self.timeout = timeout
