"""Retire a robot nobody serves, on its own MQTT session, without serving it (a shared fleet: node/share.py).

A robot handed over to a member that then dropped it (its fleet file or its ROS graph no longer lists it) before
it took it, while no other member lists it either, would stay "online, handed over" with its TD retained and
nobody serving it. Its status and TD topics are the robot's own: under the generated broker ACL only the robot's
user may write them, so the process that handed it over (which has its settings) writes them, as that robot.

It connects with the robot's own client id and session rather than a connection of its own: should a member
claim the robot at that moment, the broker orders the two (the later connection takes the session over, and
nothing this one sends afterwards is taken), so the `offline` written here can only come before that member's
`online`, never after it. Nothing the session holds is taken (commands sent to the robot meanwhile stay there
for whoever serves it next), and no `online` is published: the robot goes from "handed over" to `offline`.
"""

from __future__ import annotations

from typing import Any

from td2adaptor.model.events import td_topic
from td2adaptor.runtime.bus.bus import Message
from td2adaptor.runtime.bus.mqttbus import MqttBus
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.node.app import bus_security

#: seconds the retiring connection waits for the broker (its CONNACK, the acknowledgements)
RETIRE_TIMEOUT = 5.0


class _Untaking(MqttBus):
    """A robot's session connection that takes nothing of what the session delivers: never handled, never
    acknowledged, so the broker delivers it again on the session's next connection."""

    def _deliver(self, message: Message, mid: int | None = None) -> None:
        return


def retire(config: RuntimeConfig, model: Any, offline: Message) -> bool:
    """Publish `offline` (the robot's retained status) and clear its retained TD on the robot's own session;
    True once the broker acknowledged both. Raises `BusError` when the broker cannot be reached."""
    address, security = bus_security(config, model)
    bus = _Untaking(
        address,
        security,
        client_id=config.mqtt_client_id,
        session_expiry=config.session_expiry,  # the session stays the robot's: its next owner resumes it
        mqtt_version=config.mqtt_version,
        keepalive=config.keepalive,
        connect_timeout=RETIRE_TIMEOUT,
        reconnect_delay=(60, 60),  # one connection: a lost one is not made again (close() ends it first)
    )
    bus.connect()
    try:
        bus.publish(td_topic(config.robot, config.topic_root), b"", retain=True)
        bus.publish(offline.topic, offline.payload, retain=True)
        return bus.flush(RETIRE_TIMEOUT)
    finally:
        bus.close()
