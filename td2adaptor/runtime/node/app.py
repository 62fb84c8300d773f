"""Putting a runtime together: the bus a configuration names, and an engine serving one robot on it."""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

from td2adaptor.model import Model
from td2adaptor.model.events import EventCatalog, build_catalog, td_topic
from td2adaptor.runtime.bus.bus import Bus, Message
from td2adaptor.runtime.bus.localbus import LocalBroker, LocalBus
from td2adaptor.runtime.bus.security import (
    BrokerAddress,
    ConnectionSecurity,
    TlsOptions,
    login_name,
    parse_broker_url,
    plan_security,
)
from td2adaptor.runtime.bus.thingbus import thing_bus
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.engine import Engine, status_event
from td2adaptor.runtime.ros.port import RobotPort

if TYPE_CHECKING:
    from td2adaptor.runtime.node.discovery import Registration

log = logging.getLogger("td2adaptor.runtime")


def bus_security(
    config: RuntimeConfig, model: Model, *, env: Mapping[str, str] | None = None
) -> tuple[BrokerAddress, ConnectionSecurity]:
    """The broker of an MQTT `config.bus` and how to connect to it as the TD's security says.

    Raises `SecurityError` when the URL or the configuration does not satisfy the TD's security definitions.
    """
    address = parse_broker_url(config.bus)
    tls = None
    if config.tls_ca_file or config.tls_cert_file or config.tls_key_file:
        tls = TlsOptions(config.tls_ca_file, config.tls_cert_file, config.tls_key_file)
    security = plan_security(
        model.thing.security,
        address,
        username=config.username,
        password=config.password,
        tls=tls,
        allow_insecure=config.allow_insecure,
        env=env,
    )
    return address, security


def td_broker(config: RuntimeConfig) -> str | None:
    """The broker URL the robot's published TD names (`td_broker`, else the bus); None on a local bus without
    one. Raises `SecurityError` for a URL that is no broker's (or carries credentials)."""
    url = config.td_broker or (None if config.bus == "local" else config.bus)
    return None if url is None else parse_broker_url(url).url


def td_message(
    config: RuntimeConfig,
    model: Model,
    catalog: EventCatalog | None = None,
    *,
    env: Mapping[str, str] | None = None,
) -> Message | None:
    """The robot's Thing Description as the retained message the edge node publishes when it is online (the
    text `td2adaptor expose` writes for the same robot, broker and ROS version, with `--basic` when the node
    logs in with a user name: then the TD says `basic` even when its source says nosec, see `exposed_td`);
    None when there is no broker to name. `env`: where the user name may come from, as in `serve`."""
    broker = td_broker(config)
    if broker is None:
        return None
    from td2adaptor.model.exposed import exposed_td
    from td2adaptor.support.jsondump import dump

    td = exposed_td(
        model,
        catalog,
        robot=config.robot,
        broker=broker,
        root=config.topic_root,
        property_qos=config.property_qos,
        authenticated=config.bus != "local" and bool(login_name(config.username, env)),
    )
    text = dump(td)
    return Message(td_topic(config.robot, config.topic_root), text.encode("utf-8"), retain=True)


def open_bus(
    config: RuntimeConfig,
    model: Model,
    *,
    broker: LocalBroker | None = None,
    env: Mapping[str, str] | None = None,
    announce: Sequence[Message] = (),
    online: bool = True,
) -> Bus:
    """`local` (the process-wide in-process broker, or `broker`) or MQTT, secured as the TD says; `announce`
    (retained messages) is published on every connection, before the online status. `online=False`: the first
    connection publishes no online status (`serve`: the robot's status keeper publishes the first one, once the
    missions the last run left are followed again and the robot's ROS side was looked at), the next ones publish
    the last status published.

    Raises `SecurityError` when the configuration does not satisfy the TD's security definitions. When the TD
    requires authentication, every connection of the MQTT bus first checks that the broker refuses anonymous
    clients (unless `allow_anonymous_broker`): the first one's `connect()` raises `SecurityError` if it does
    not, a later one stops serving that broker (`MqttBus.refused`, see `serve`).
    """
    from td2adaptor.runtime.node.status import owner_fields

    will = status_event(config, model, "offline", **owner_fields())  # the last owner: the process that died
    birth = status_event(config, model, "online", **owner_fields(), missions=0) if online else None
    if config.bus == "local":
        return LocalBus(broker, config.mqtt_client_id, will=will, birth=birth, announce=announce)
    from td2adaptor.runtime.bus.mqttbus import MqttBus  # paho only when it is used

    address, security = bus_security(config, model, env=env)
    verify = None
    if security.username and not config.allow_anonymous_broker:
        verify = _anonymous_check(address, security.tls, config.mqtt_version)
    return MqttBus(
        address,
        security,
        client_id=config.mqtt_client_id,
        will=will,
        birth=birth,
        announce=announce,
        no_local=True,  # its command filters match its own property values' topics (engine.py drops them)
        session_expiry=config.session_expiry,
        mqtt_version=config.mqtt_version,
        keepalive=config.keepalive,
        verify=verify,
    )


def _anonymous_check(address: BrokerAddress, tls: TlsOptions | None, mqtt_version: str) -> Callable[[], str | None]:
    """The check the node's connection runs each time it connects, before anything from it is handled, when
    the TD requires authentication: does the broker refuse a client without credentials? A broker restarted
    with anonymous access while the node runs would otherwise let anyone command the robot."""
    from td2adaptor.runtime.bus.mqttbus import accepts_anonymous

    def check() -> str | None:
        if not accepts_anonymous(address, tls, mqtt_version=mqtt_version):
            return None
        return (
            f"the MQTT broker at {address} accepts clients without credentials, although the Thing "
            "Description requires authentication: anyone who reaches it could command the robot or forge "
            "its feedback. Configure the broker to refuse anonymous clients (mosquitto: allow_anonymous "
            "false; see docs/security.md), or run anyway with --allow-anonymous-broker"
        )

    return check


def serve(
    model: Model,
    port: RobotPort,
    config: RuntimeConfig,
    *,
    broker: LocalBroker | None = None,
    env: Mapping[str, str] | None = None,
    distro: str | None = None,
    prepare: Callable[[Engine], None] | None = None,
) -> Engine:
    """Connect and start serving (the robot's TD published, retained, with the online status, and registered
    with the configured TD directory); `Engine.stop()` ends it (and clears the TD, here and there). `distro`:
    the robot's ROS version ("ros1" or "ros2"), whose message layouts the events and the TD follow; by default
    the one `port` declares in a `distro` attribute (a ROS 1 bridge's port says "ros1"), else "ros2". `prepare`
    is called with the engine before it starts.

    The engine's bus is wrapped in a `ThingBus`: WoT consumers of the published TD use the robot on its WoT
    topics, native clients on the envelope topics."""
    catalog = build_catalog(model, port_distro(port) if distro is None else distro)
    td = td_message(config, model, catalog, env=env)
    announce = () if td is None else (td,)
    # no online status on connecting: the first one says what the recovery follows (engine.start) and what the
    # first look at the robot saw (status.py); an `online, missions: 0` before it was wrong for a moment
    raw = open_bus(config, model, broker=broker, env=env, announce=announce, online=False)
    bus = thing_bus(
        raw,
        catalog,
        config.robot,
        config.topic_root,
        correlation_ids=config.require_id_and_time,
    )
    engine = Engine(model, port, bus, config, catalog=catalog, td=td)
    if prepare is not None:  # before it serves (a shared fleet: what the robot's last owner admitted, share.py)
        prepare(engine)
    if config.bus != "local":
        from td2adaptor.runtime.bus.mqttbus import MqttBus

        if isinstance(raw, MqttBus):
            raw.on_refused = engine.halt  # a reconnection the broker check refused: the engine halts
    engine.start()
    from td2adaptor.runtime.node.status import watch

    keeper = watch(engine, raw, port)  # the robot's status kept true: its ROS side, missions, last error
    registration = register(config, td)
    if registration is not None:
        engine.on_stop.append(registration.stop)
        keeper.follow_presence(registration.reflect)  # the directory says whether the robot is there
    return engine


def port_distro(port: RobotPort) -> str:
    """The ROS version `port` declares (its `distro` attribute), "ros2" when it declares none."""
    distro = getattr(port, "distro", None)
    return distro if isinstance(distro, str) else "ros2"


def register(config: RuntimeConfig, td: Message | None) -> Registration | None:
    """Start keeping the robot's TD registered with `config.directory` (None when none is configured)."""
    if config.directory is None:
        return None
    if td is None:
        log.warning(
            "robot %s: no Thing Description to register with the directory (a local bus names no broker; "
            "set td_broker)",
            config.robot,
        )
        return None
    from td2adaptor.runtime.node.discovery import Directory, Registration

    directory = Directory(config.directory, token=config.directory_token, ca_file=config.directory_ca_file)
    try:
        registration = Registration(directory, td.payload, robot=config.robot, ttl=config.directory_ttl)
    except ValueError as exc:  # a TD without id: logged, the robot is served all the same
        log.error("%s", exc)
        return None
    registration.start()
    return registration


def serve_fleet(
    model: Model,
    make_port: Callable[[RuntimeConfig], RobotPort],
    configs: Sequence[RuntimeConfig],
    *,
    broker: LocalBroker | None = None,
    env: Mapping[str, str] | None = None,
    distro: str | None = None,
) -> list[Engine]:
    """One engine per robot in one process (each with its own bus client and port); all or none start.
    `distro` as in `serve` (by default each port's own)."""
    engines: list[Engine] = []
    try:
        for config in configs:
            engines.append(serve(model, make_port(config), config, broker=broker, env=env, distro=distro))
    except BaseException:
        for engine in engines:
            engine.stop()
        raise
    return engines
