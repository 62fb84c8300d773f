# The parts of rospy that the generated adaptor uses.
from collections.abc import Callable
from typing import Any

from rospy import core as core
from rospy import exceptions as exceptions
from rospy.exceptions import ROSException as ROSException
from rospy.exceptions import ROSInterruptException as ROSInterruptException
from rospy.exceptions import ROSSerializationException as ROSSerializationException

class ServiceException(Exception): ...

class ServiceProxy:
    resolved_name: str
    persistent: bool
    transport: Any
    def __init__(
        self, name: str, service_class: Any, persistent: bool = False, headers: dict[str, str] | None = None
    ) -> None: ...
    def call(self, *args: Any, **kwds: Any) -> Any: ...
    def __call__(self, *args: Any, **kwds: Any) -> Any: ...
    def close(self) -> None: ...

class Publisher:
    def __init__(
        self,
        name: str,
        data_class: Any,
        subscriber_listener: Any = None,
        tcp_nodelay: bool = False,
        latch: bool = False,
        headers: dict[str, str] | None = None,
        queue_size: int | None = None,
    ) -> None: ...
    def publish(self, *args: Any, **kwds: Any) -> None: ...
    def unregister(self) -> None: ...
    def get_num_connections(self) -> int: ...

class Subscriber:
    resolved_name: str
    impl: Any
    def __init__(
        self,
        name: str,
        data_class: Any,
        callback: Callable[..., None] | None = None,
        callback_args: Any = None,
        queue_size: int | None = None,
        buff_size: int = 65536,
        tcp_nodelay: bool = False,
    ) -> None: ...
    def unregister(self) -> None: ...
    def get_num_connections(self) -> int: ...

def init_node(
    name: str,
    argv: list[str] | None = None,
    anonymous: bool = False,
    log_level: int | None = None,
    disable_rostime: bool = False,
    disable_rosout: bool = False,
    disable_signals: bool = False,
    xmlrpc_port: int = 0,
    tcpros_port: int = 0,
) -> None: ...
def wait_for_service(service: str, timeout: float | None = None) -> None: ...
def signal_shutdown(reason: str) -> None: ...
def is_shutdown() -> bool: ...
def get_caller_id() -> str: ...
def get_name() -> str: ...
def resolve_name(name: str, caller_id: str | None = None) -> str: ...
def logerr(msg: str, *args: Any) -> None: ...
def logwarn(msg: str, *args: Any) -> None: ...
def loginfo(msg: str, *args: Any) -> None: ...
