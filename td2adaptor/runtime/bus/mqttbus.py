"""The bus on a real MQTT broker, with paho-mqtt 2.x.

MQTT 5 (or 3.1.1 for brokers that speak only that: `mqtt_version`), QoS 1 both ways, a persistent session
(`clean_start=False` with a session expiry; in 3.1.1 `clean_session=False`, kept as long as the broker keeps
sessions) so that neither side loses messages while the other is away (except on the filters subscribed at
QoS 0, which the broker does not queue for an absent client). One thread serves every connection of the
process (mqttloop.py) and reconnects with back-off; paho keeps unacknowledged QoS 1 publishes and resends
them; we resubscribe and republish the birth message on every (re)connect, and on a reconnect every retained
message this client published last on a topic (property values, their WoT form): a broker restarted without
persistence has forgotten them, and a client that reads a retained value (node-wot's readProperty) would
otherwise wait until the value changes.
The will (the retained `offline` status) is published by the broker when the connection drops uncleanly.
`verify` (the anonymous-broker check, app.py) runs on every connection before anything of it is handled; a
connection that fails it ends the client's service of the broker for good (`refused`, `on_refused`). It runs
on a helper thread while the connection is held: what arrives meanwhile is kept unhandled (and unacknowledged:
a held connection writes nothing), then handled in order once the check passes.
A QoS 1 message is acknowledged to the broker (PUBACK) once it is taken, not when paho reads it (paho's manual
acknowledgements): at once after the handlers returned, or, for a subscription made with `acks` (the engine's
commands), when its handler calls `Message.ack` (the engine: once it admitted or answered it). A message never
acknowledged stays the session's: the broker delivers it again on the session's next connection, this client's
after a reconnection or the next process's that connects with the same client id (a restart, a takeover). The
acknowledgements go in the order the messages came, on the serving thread.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import socket
import ssl
import threading
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTErrorCode, MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties
from paho.mqtt.reasoncodes import ReasonCode
from paho.mqtt.subscribeoptions import SubscribeOptions

from td2adaptor.runtime.bus.bus import BusError, Handler, Message, check_qos, topic_matches, valid_filter, valid_topic
from td2adaptor.runtime.bus.mqttloop import Link, ServedClient, shared
from td2adaptor.runtime.bus.security import (
    ENV_PASSWORD,
    ENV_USERNAME,
    BrokerAddress,
    ConnectionSecurity,
    SecurityError,
    TlsOptions,
)

log = logging.getLogger("td2adaptor.runtime.bus")

_TAKEN_OVER = 142  # MQTT 5 DISCONNECT reason: Session taken over (node/owner.py)
_AUTH_REFUSALS = {134, 135}  # Bad user name or password, Not authorized (paho maps 3.1.1's 4 and 5 onto them)
MQTT_VERSIONS = ("5", "3.1.1")
#: topics whose matching handlers a client remembers (then it forgets them all and starts again)
ROUTES_KEPT = 4096
#: the topic filter `round_trip` unsubscribes from: one nobody subscribes to (the broker answers all the same)
ROUND_TRIP = ".td2adaptor/round-trip"


def _no_delay(_client: mqtt.Client, _userdata: Any, sock: Any) -> None:
    """Small events must not wait for Nagle's algorithm (40 ms stalls against delayed ACKs)."""
    try:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    except (OSError, AttributeError):
        pass  # not a TCP socket (e.g. unix or a websocket wrapper)


class _ClosingSSLSocket(ssl.SSLSocket):
    """paho leaves the socket of a failed TLS handshake open; this one closes itself."""

    def do_handshake(self, block: bool = False) -> None:
        try:
            super().do_handshake(block)
        except BaseException:
            self.close()
            raise


def tls_context(options: TlsOptions) -> ssl.SSLContext:
    """Verify the broker (its CA, else the system's; host name checked); present a client certificate if given."""
    try:
        context = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=options.ca_file)
        if options.cert_file:
            context.load_cert_chain(options.cert_file, options.key_file)
    except (OSError, ssl.SSLError) as exc:
        raise BusError(f"cannot load the TLS files: {exc}") from None
    context.sslsocket_class = _ClosingSSLSocket
    return context


# OpenSSL's X509_V_ERR_* codes of the faults a broker's certificate can have, and what each means to the user
_NOT_YET_VALID, _EXPIRED = 9, 10
_HOSTNAME_MISMATCH, _IP_ADDRESS_MISMATCH = 62, 64
_UNKNOWN_ISSUER = {2, 18, 19, 20, 21}  # no issuer certificate, self-signed (in the chain), no local issuer


def _tls_hint(exc: ssl.SSLError, tls: TlsOptions | None, host: str) -> str:
    """What is wrong with the broker's certificate, in words, and what to change: its dates, the name or address
    it is for, or the CA the node trusts (only when the CA is the fault: an expired certificate of the right CA
    is not fixed by another tls_ca_file)."""
    if not isinstance(exc, ssl.SSLCertVerificationError):
        return ""
    code = exc.verify_code
    if code == _EXPIRED:
        return (
            " (the broker's certificate, or a certificate that signed it, has expired: renew it on the broker, "
            "or check this machine's clock)"
        )
    if code == _NOT_YET_VALID:
        return (
            " (the broker's certificate, or a certificate that signed it, is not valid yet: check this machine's "
            "clock and the certificate's start date)"
        )
    if code == _IP_ADDRESS_MISMATCH:
        return (
            f" (the broker's certificate is not for the IP address {host!r}: connect by a name or address it "
            "names in its subjectAltName, or give the broker a certificate that names this address)"
        )
    if code == _HOSTNAME_MISMATCH:
        return (
            f" (the broker's certificate is not for the host name {host!r}: connect by a name or address it "
            "names in its subjectAltName, or give the broker a certificate that names this host)"
        )
    if code in _UNKNOWN_ISSUER:
        trusted = f"the CA in tls_ca_file {tls.ca_file}" if tls is not None and tls.ca_file else "the system's CAs"
        return (
            f" (this node trusts {trusted}, which did not sign the broker's certificate: set tls_ca_file "
            "(TD2ADAPTOR_TLS_CA_FILE) to the CA certificate that did)"
        )
    return f" (the broker's certificate was refused: {exc.verify_message})"


class MqttBus:
    """One MQTT client; `connect()` returns once the broker has accepted it (or raises `BusError`, or
    `SecurityError` when the first connection fails `verify`)."""

    def __init__(
        self,
        address: BrokerAddress,
        security: ConnectionSecurity | None = None,
        *,
        client_id: str,
        will: Message | None = None,
        birth: Message | None = None,
        announce: Sequence[Message] = (),
        clean_start: bool = False,
        session_expiry: int = 3600,
        mqtt_version: str = "5",
        keepalive: int = 30,
        connect_timeout: float = 10.0,
        reconnect_delay: tuple[int, int] = (1, 4),
        retain_as_published: bool = True,
        no_local: bool = False,
        verify: Callable[[], str | None] | None = None,
    ) -> None:
        self.address = address
        self.security = security or ConnectionSecurity()
        self.client_id = client_id
        self.will = will
        self.birth = birth
        self.announce = tuple(announce)
        self.clean_start = clean_start
        self.session_expiry = session_expiry
        if mqtt_version not in MQTT_VERSIONS:
            raise BusError(f"MQTT version {mqtt_version!r} is not supported (supported: {', '.join(MQTT_VERSIONS)})")
        self.mqtt_version = mqtt_version
        self.keepalive = keepalive
        self.connect_timeout = connect_timeout
        self.reconnect_delay = reconnect_delay
        self.retain_as_published = retain_as_published  # MQTT 5; off: only a new subscription's retained are flagged
        self.no_local = no_local  # MQTT 5: the broker sends this client none of what it published itself
        self.connects = 0  # successful CONNACKs, for tests and logs
        self.probe = False  # a connection made only to learn what the broker allows: its refusal is no error
        self.verify = verify  # run on every connection before anything of it is handled: why not to serve, or None
        self.refused: str | None = None  # why this client stopped serving the broker (a connection failed `verify`)
        self.on_refused: Callable[[str], None] | None = None  # told `refused` when a reconnection fails `verify`
        #: run on every reconnection (with `verify`, on a helper) before anything of it is handled: what took this
        #: client's session over (another edge node serves the robot now: node/owner.py), or None; if something
        #: did, this client stops serving
        self.owned: Callable[[], str | None] | None = None
        self._retained: dict[str, tuple[bytes, int]] = {}  # topic -> (payload, QoS) of the last retained publish
        self._retained_inflight: dict[int, str] = {}  # QoS 1 retained publishes not acknowledged: paho resends them
        self._refusals_said: set[str] = set()  # topics ("" for any other) of publishes the broker refused, logged
        self._retain_lock = threading.RLock()  # orders retained publishes with their republication on reconnect
        self._handlers: list[tuple[str, Handler, bool]] = []  # (filter, handler, whether it acknowledges itself)
        self._routes: dict[str, list[tuple[Handler, bool]]] = {}  # topic -> its handlers, of the topics seen
        self._qos: dict[str, int] = {}  # each filter's QoS: the highest any of its subscriptions asked for
        self._lock = threading.Condition()
        self._pending: set[int] = set()
        self._acked_early: set[int] = set()
        self._unacked: set[int] = set()  # QoS 0 message ids whose on_publish (at the write) has not come yet
        self._subacked: set[int] = set()
        self._first_subscribe: int | None = None  # the message id of the subscriptions sent on the first CONNACK
        self._first_epoch = -1  # the first accepted connection's `_epoch` (connect() checks it is still there)
        self._connack = threading.Event()
        self._refusal: ReasonCode | None = None
        self._dropped: str | None = None
        self._connected = False
        self._client: mqtt.Client | None = None
        self._link: Link | None = None  # how the process's serving loop serves the client (None: `DrivenBus`)
        #: what arrived while `verify` checks the connection (with its message id at QoS 1), or None
        self._held: list[tuple[Message, int | None]] | None = None
        #: (serving thread) the QoS 1 messages of this connection not acknowledged yet, in the order they came:
        #: message id -> taken (its acknowledgement is due once every one before it is taken too)
        self._inbox: OrderedDict[int, bool] = OrderedDict()
        self._inbox_lock = threading.Lock()  # paho may tell a connection's loss on a publisher's thread
        self._epoch = 0  # the connection's number: an acknowledgement is for the connection its message came on
        self._flushed: list[tuple[set[int], Callable[[], None]]] = []  # `when_flushed`: what each still waits for
        #: (`round_trip`) UNSUBSCRIBE message id -> (the connection it was sent on, who waits for its answer)
        self._trips: dict[int, tuple[int, Callable[[bool], None]]] = {}
        self._unsubacked: dict[int, int] = {}  # UNSUBSCRIBE message id -> its connection: answered before registered

    @classmethod
    def sessionless(
        cls,
        address: BrokerAddress,
        security: ConnectionSecurity | None,
        purpose: str,
        *,
        mqtt_version: str = "5",
        keepalive: int = 30,
        connect_timeout: float = 10.0,
        will: Message | None = None,
        client_id: str | None = None,
    ) -> MqttBus:
        """A connection that keeps no session on the broker (clean start, expiry 0): what a look at the bus,
        a fleet's member records, an owner claim, an admin request, a probe or the dashboard needs. Nothing is
        queued for it while it is away, and its id (`td2adaptor-<purpose>-<random>` unless `client_id` is
        given) never takes over a robot's session."""
        return cls(
            address,
            security,
            client_id=client_id or f"td2adaptor-{purpose}-{os.urandom(6).hex()}"[:128],
            will=will,
            clean_start=True,
            session_expiry=0,
            mqtt_version=mqtt_version,
            keepalive=keepalive,
            connect_timeout=connect_timeout,
        )

    @property
    def connected(self) -> bool:
        return self._connected

    # -- connection ----------------------------------------------------------------------------------------

    def _make_client(self) -> mqtt.Client:
        if self.mqtt_version == "5":
            client = ServedClient(
                CallbackAPIVersion.VERSION2,
                client_id=self.client_id,
                protocol=MQTTProtocolVersion.MQTTv5,
                reconnect_on_failure=False,  # paho would reconnect inside a read (blocking): the loop does it
                manual_ack=True,  # a message is acknowledged once taken (`_taken`)
            )
        else:  # 3.1.1: the session flag is set here, and there are no CONNECT properties
            client = ServedClient(
                CallbackAPIVersion.VERSION2,
                client_id=self.client_id,
                clean_session=self.clean_start,
                protocol=MQTTProtocolVersion.MQTTv311,
                reconnect_on_failure=False,
                manual_ack=True,
            )
        client.max_queued_messages_set(0)  # unlimited: nothing published while offline is dropped
        client.max_inflight_messages_set(200)
        sec = self.security
        if sec.username:
            client.username_pw_set(sec.username, sec.password)
        if sec.tls is not None or self.address.tls:
            client.tls_set_context(tls_context(sec.tls or TlsOptions()))
        if self.will is not None:
            client.will_set(self.will.topic, self.will.payload, qos=1, retain=self.will.retain)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        client.on_publish = self._on_publish
        client.on_subscribe = self._on_subscribe
        client.on_unsubscribe = self._on_unsubscribe
        client.on_socket_open = _no_delay
        return client

    def connect(self) -> None:
        if self._client is not None:
            return
        client = self._make_client()
        self._connack.clear()
        self._refusal = None
        self._dropped = None
        try:
            if self.mqtt_version == "5":
                props = Properties(PacketTypes.CONNECT)  # type: ignore[no-untyped-call]
                props.SessionExpiryInterval = self.session_expiry
                client.connect(
                    self.address.host,
                    self.address.port,
                    self.keepalive,
                    clean_start=self.clean_start,
                    properties=props,
                )
            else:
                client.connect(self.address.host, self.address.port, self.keepalive)
        except ssl.SSLError as exc:
            hint = _tls_hint(exc, self.security.tls, self.address.host)
            raise BusError(f"TLS handshake with the MQTT broker at {self.address} failed: {exc}{hint}") from None
        except OSError as exc:
            raise BusError(f"cannot reach the MQTT broker at {self.address}: {exc.strerror or exc}") from None
        self._client = client
        self._start(client)
        if not self._await_connack(client):
            self._abort()
            hint = (
                " (a broker that speaks only MQTT 3.1.1 does not answer an MQTT 5 client: set mqtt_version to 3.1.1)"
                if self.mqtt_version == "5"
                else ""
            )
            raise BusError(f"the MQTT broker at {self.address} did not answer within {self.connect_timeout:g} s{hint}")
        if self._dropped is not None and self._refusal is None and self.connects == 0:
            self._abort()
            raise BusError(
                f"the MQTT broker at {self.address} closed the connection before accepting it ({self._dropped}); "
                "with TLS, check that the broker accepts this client's certificate"
            )
        if self.refused is not None:
            self._abort()
            raise SecurityError(self.refused)
        refusal = self._refusal
        if refusal is not None:
            self._abort()
            if refusal.value in _AUTH_REFUSALS:
                who = f"user {self.security.username!r}" if self.security.username else "an anonymous client"
                raise BusError(
                    f"the MQTT broker at {self.address} refused {who}: {refusal.getName()} (check the MQTT "
                    f"username and password in the configuration or in {ENV_USERNAME} / {ENV_PASSWORD})"
                )
            raise BusError(f"the MQTT broker at {self.address} refused the connection: {refusal.getName()}")
        if not self._await_first_subscribe():
            self._abort()
            raise BusError(
                f"the MQTT broker at {self.address} closed the connection right after accepting it: another client "
                f"connected with this client id ({self.client_id}) and took its session over? (a second edge node "
                "for the same robot)"
            )

    def _start(self, client: mqtt.Client) -> None:
        """Start serving the connection: the process's serving loop (`DrivenBus` serves it from its owner's)."""
        self._link = Link(shared(), client, self.reconnect_delay, self.client_id)
        self._link.may_reconnect = self._may_reconnect
        self._link.start()

    def _stop(self, client: mqtt.Client) -> None:
        """Disconnect cleanly and stop serving the connection (waiting at most `connect_timeout` for it)."""
        link, self._link = self._link, None
        if link is not None:
            link.close(self.connect_timeout)

    def _await_connack(self, _client: mqtt.Client) -> bool:
        return self._connack.wait(self.connect_timeout)

    def _await_first_subscribe(self) -> bool:
        """Return from connect() only once the broker has taken the subscriptions made before it: an event
        published right after (an application that sees this robot online) must find them in place; without a
        session of ours the broker keeps nothing for filters it does not know yet. False: the first connection
        was lost before (mosquitto 2.0 closes a connection whose session another one took over without MQTT 5's
        reason: only this says so), and its reconnection would take the session back."""
        with self._lock:
            mid = self._first_subscribe
            if mid is not None:
                self._await_suback(mid, "the subscriptions", self._first_epoch)
                self._first_subscribe = None
            return self._epoch == self._first_epoch

    def _await_suback(self, mid: int, what: str, epoch: int) -> None:
        """Wait (lock held) at most `connect_timeout` for the SUBACK of subscribe message `mid` sent on connection
        `epoch` (not on the serving thread, which reads it); not once that connection is lost."""
        if self._link is not None and self._link.loop.on_thread():
            return
        if not self._lock.wait_for(lambda: mid in self._subacked or self._epoch != epoch, self.connect_timeout):
            log.warning("no SUBACK for %s within %g s", what, self.connect_timeout)
        self._subacked.discard(mid)

    def _abort(self) -> None:
        client, self._client = self._client, None
        if client is not None:
            self._stop(client)

    def _on_connect(
        self, client: mqtt.Client, _userdata: Any, flags: Any, reason: ReasonCode, _props: Properties | None
    ) -> None:
        self._forget_inbox()  # before anything arrives on the new connection
        if reason.is_failure:
            self._refusal = reason
            self._connack.set()
            if not self.probe:
                log.error("MQTT broker %s refused the connection: %s", self.address, reason.getName())
            return
        link = self._link
        owned = self.owned is not None and self.connects > 0
        if (self.verify is not None or owned) and link is not None:  # checked on a helper; held meanwhile
            self._held = []
            link.hold()
            sock = client.socket()
            link.loop.run_blocking(lambda: self._check(link, client, sock, flags))
            return
        refusal = self._verified()
        if refusal is not None:
            self._stop_serving(client, refusal)
            return
        taken = self._owned() if owned else None
        if taken is not None:
            self._taken_over(client, taken)
            return
        self._accept(client, flags)

    def _check(self, link: Link, client: mqtt.Client, sock: Any, flags: Any) -> None:
        """(Helper thread) `verify` the connection whose socket is `sock`, and on a reconnection ask `owned`;
        the verdicts go back to the loop."""
        refusal = self._verified()
        taken = self._owned() if refusal is None and self.connects > 0 else None
        link.loop.call_soon(lambda: self._checked(client, sock, flags, refusal, taken))

    def _checked(self, client: mqtt.Client, sock: Any, flags: Any, refusal: str | None, taken: str | None) -> None:
        """(Serving thread) the check's verdict: stop serving the broker, or handle what was held and go on. A
        connection lost during its check is not served: its successor is checked in turn."""
        link = self._link
        if client is not self._client or link is None:
            return  # closed meanwhile
        if refusal is not None:
            self._stop_serving(client, refusal)
            return
        if client.socket() is not sock:
            return
        if taken is not None:
            self._taken_over(client, taken)
            return
        held, self._held = self._held or [], None
        self._accept(client, flags)
        for message, mid in held:
            self._deliver(message, mid)
        link.release()

    def _accept(self, client: mqtt.Client, flags: Any) -> None:
        """A connection to serve: subscribe, publish again what the broker may have lost, then the birth."""
        self.connects += 1
        self._connected = True  # from now on what arrives on this connection is handled
        with self._lock:
            patterns = [(p, self._qos[p]) for p in dict.fromkeys(p for p, _h, _a in self._handlers)]
        if self.connects == 1:
            self._first_epoch = self._epoch
        if patterns:
            rc, mid = self._subscribe(client, patterns)
            if self.connects == 1 and rc is MQTTErrorCode.MQTT_ERR_SUCCESS and mid is not None:
                self._first_subscribe = mid  # connect() waits for its SUBACK
        announced = (*self.announce, *([self.birth] if self.birth is not None else []))
        if self.connects > 1:
            self._republish(client, {m.topic for m in announced})
        for message in announced:
            self._send(client, message.topic, message.payload, message.retain)
        if self.connects > 1:
            log.info("reconnected to %s (session present: %s)", self.address, flags.session_present)
        self._connack.set()

    def _republish(self, client: mqtt.Client, skip: set[str]) -> None:
        """Publish again the last retained message of each topic (but `skip`, and those paho resends itself):
        the broker may have lost them (a restart without persistence); to a broker that kept them it is the
        same message again. Before the birth message: a client that sees the robot online finds its values."""
        with self._retain_lock:
            with self._lock:
                resent = set(self._retained_inflight.values())
            for topic, (payload, qos) in list(self._retained.items()):
                if topic not in skip and topic not in resent:
                    self._send(client, topic, payload, True, qos)

    def _verified(self) -> str | None:
        """`verify`'s verdict on this connection; a check that cannot be made refuses it (fails closed)."""
        if self.verify is None:
            return None
        try:
            return self.verify()
        except Exception:  # noqa: BLE001 - the thread that runs it must live; the details go to the log
            log.exception("checking the MQTT broker at %s failed", self.address)
            return f"the check of the MQTT broker at {self.address} failed (see the log), so it is not trusted"

    def _owned(self) -> str | None:
        """`owned`'s verdict; one that cannot be made lets the connection serve (the broker's own rules stand)."""
        if self.owned is None:
            return None
        try:
            return self.owned()
        except Exception:  # noqa: BLE001 - the thread that runs it must live; the details go to the log
            log.exception("checking who serves this robot on %s failed", self.address)
            return None

    def _may_reconnect(self) -> bool:
        """(Helper thread, before reconnecting) Ask `owned` first: a broker that took the session over closes the
        connection without saying so (mosquitto 2.0: no "Session taken over"), and reconnecting would take the
        session back from the other client, which serves the robot now (node/share.py: two processes that both
        claimed it). If another serves it, this client stops serving without reconnecting."""
        if self.owned is None or self.refused is not None or self.connects == 0:
            return self.refused is None
        try:
            taken = self.owned()
        except Exception as exc:  # noqa: BLE001 - the broker away, as the reconnection will find: it is tried
            log.debug("before reconnecting to %s, who serves the robot could not be read: %s", self.address, exc)
            return True
        if taken is None:
            return True
        self.refused = (
            f"stopped serving: another client connected to the MQTT broker at {self.address} with this client id "
            f"({self.client_id}) and {taken}: a second edge node for the same robot?"
        )
        log.error("%s", self.refused)
        if self.on_refused is not None:
            self._tell_refused(self.on_refused, self.refused)
        return False

    def _taken_over(self, client: mqtt.Client, what: str) -> None:
        """Another connection with this client id took the session over (a second edge node for the same robot,
        started at the same moment as this one: node/owner.py): MQTT 5's "Session taken over", or `owned` said
        so on reconnecting. Taking it back would push the two off the broker in turn for ever: this client stops
        serving (no reconnection; the connection is dropped without acknowledging what it held, which the broker
        then delivers to the other, whose reconnection also publishes its status again); `on_refused` is told."""
        self.refused = (
            f"stopped serving: another client connected to the MQTT broker at {self.address} with this client id "
            f"({self.client_id}) and {what}: a second edge node for the same robot?"
        )
        self._connected = False
        self._held = None  # never handled
        self._trips_lost()
        log.error("%s", self.refused)
        link = self._link
        if link is None:
            client.disconnect()
        else:
            link.drop()
        if self.on_refused is not None:
            refused, hook = self.refused, self.on_refused
            if link is None:
                self._tell_refused(hook, refused)
            else:  # the hook may block (the engine halts): not on the serving thread
                link.loop.run_blocking(lambda: self._tell_refused(hook, refused))

    def _stop_serving(self, client: mqtt.Client, why: str) -> None:
        """A connection failed `verify`: handle nothing from it, disconnect, and stay away from this broker
        (on the first connection `connect()` raises; on a later one `on_refused` is told, and the retained
        `offline` status keeps the robot from looking online there)."""
        first = self.connects == 0 and self.refused is None
        self.refused = why if first else f"stopped serving: after reconnecting, {why}"
        self._connected = False
        self._held = None  # never handled
        self._trips_lost()
        link = self._link
        if not first:
            log.error("%s", self.refused)
        if link is None:  # served by its owner (`DrivenBus`): tell the others it is gone, and end it
            if not first and self.will is not None:
                self._send(client, self.will.topic, self.will.payload, self.will.retain)
            client.disconnect()
        elif first:
            link.close(self.connect_timeout)  # the robot was never online there: a clean disconnect
        else:
            link.drop()  # nothing more is written there; the broker publishes the will (offline)
        self._connack.set()
        if not first and self.on_refused is not None:
            refused, hook = self.refused, self.on_refused
            if link is None:
                self._tell_refused(hook, refused)
            else:  # the hook may block (the engine halts): not on the serving thread
                link.loop.run_blocking(lambda: self._tell_refused(hook, refused))

    def _tell_refused(self, hook: Callable[[str], None], refused: str) -> None:
        try:
            hook(refused)
        except Exception:  # noqa: BLE001 - never let a hook kill a thread that serves connections
            log.exception("while stopping serving %s", self.address)

    def _on_disconnect(
        self, _client: mqtt.Client, _userdata: Any, _flags: Any, reason: ReasonCode, _props: Properties | None
    ) -> None:
        self._connected = False
        self._held = None  # unacknowledged: the broker delivers them again on the next connection
        self._forget_inbox()  # as is every message not acknowledged yet: its acknowledgement would go nowhere
        with self._lock:
            self._unacked.clear()  # paho drops the QoS 0 messages it had not written yet
            self._lock.notify_all()  # a SUBACK awaited on it will not come (`_await_suback`)
        if self.connects == 0 and not self._connack.is_set():  # dropped before any CONNACK: fail fast
            self._dropped = reason.getName()
            self._connack.set()
        if reason.value == _TAKEN_OVER and self._client is not None and self.refused is None:
            self._taken_over(_client, "took its session over")
            return
        if self._client is not None and reason.value != 0 and not self.probe:  # a probe refused: what it asked
            log.warning("lost the MQTT broker %s (%s); reconnecting", self.address, reason.getName())

    def _on_message(self, _client: mqtt.Client, _userdata: Any, msg: mqtt.MQTTMessage) -> None:
        mid: int | None = None
        if msg.qos > 0:  # acknowledged once taken (`_taken`), in this order
            mid = msg.mid
            with self._inbox_lock:
                self._inbox[mid] = False
        message = Message(msg.topic, bytes(msg.payload), bool(msg.retain))
        held = self._held
        if held is not None:  # the connection is being checked: handled once it passes
            held.append((message, mid))
            return
        if not self._connected:  # a connection that failed `verify`: nothing of it is handled (nor acknowledged)
            return
        self._deliver(message, mid)

    def _deliver(self, message: Message, mid: int | None = None) -> None:
        topic = message.topic
        with self._lock:  # an edge node subscribes to dozens of filters: match each topic once, not every time
            handlers = self._routes.get(topic)
            if handlers is None:
                handlers = [(h, a) for p, h, a in self._handlers if topic_matches(p, topic)]
                if len(self._routes) >= ROUTES_KEPT:
                    self._routes.clear()
                self._routes[topic] = handlers
        takers = sum(1 for _h, acks in handlers if acks) if mid is not None else 0
        if takers and mid is not None:  # their handlers acknowledge it (`Message.ack`)
            ack = self._acker(self._epoch, mid, takers)
            message = Message(message.topic, message.payload, message.retain, message.origin, ack)
        for handler, acks in handlers:
            try:
                handler(message)
            except Exception:
                # never let a handler bug stop the thread that serves every connection
                log.exception("bus handler failed on %s", topic)
                if acks and message.ack is not None:
                    message.ack()  # it will not: taken, so that the messages after it are acknowledged too
        if mid is not None and not takers:
            self._taken(self._epoch, mid)

    # -- acknowledgements of QoS 1 messages (manual: once taken) -------------------------------------------

    def _acker(self, epoch: int, mid: int, takers: int) -> Callable[[], None]:
        """What acknowledges message `mid` of connection `epoch` once each of its `takers` handlers called it."""
        if takers == 1:
            return functools.partial(self._ack, epoch, mid)
        left = [takers]
        lock = threading.Lock()

        def ack() -> None:
            with lock:
                left[0] -= 1
                last = left[0] == 0
            if last:
                self._ack(epoch, mid)

        return ack

    def _ack(self, epoch: int, mid: int) -> None:
        """(any thread) Message `mid` is taken: acknowledged on the serving thread (`_taken`)."""
        link = self._link
        if link is None or link.loop.on_thread():
            self._taken(epoch, mid)
        else:
            link.loop.call_soon(functools.partial(self._taken, epoch, mid))

    def _taken(self, epoch: int, mid: int) -> None:
        """(serving thread) Acknowledge message `mid` of connection `epoch`, and the messages after it that were
        taken before it: MQTT acknowledges QoS 1 messages in the order they came. One of a connection gone
        since is not (the broker delivers it again on the next)."""
        due: list[int] = []
        with self._inbox_lock:
            inbox = self._inbox
            if epoch != self._epoch or mid not in inbox:
                return
            inbox[mid] = True
            while inbox:
                first = next(iter(inbox))
                if not inbox[first]:
                    break
                del inbox[first]
                due.append(first)
        client = self._client
        if client is not None:
            for taken in due:  # not under the lock: paho writes, and may tell the connection is lost
                client.ack(taken, 1)

    def _forget_inbox(self) -> None:
        """The connection is gone (or a new one begins): what it delivered and nobody acknowledged is the
        broker's, delivered again on the session's next connection."""
        with self._inbox_lock:
            self._epoch += 1
            self._inbox.clear()
        self._trips_lost()

    def round_trip(self, then: Callable[[bool], None]) -> None:
        """`then(True)` once the broker answered a request this connection sends now, `then(False)` once the
        connection is lost first (or is not there): whether this connection still served its session a moment ago,
        its socket read up to then (node/share.py: a goal is sent only then). A connection whose session another
        client took over never answers: mosquitto just closes its socket, which may still look open here; the
        answer cannot come before the socket's end is read. The request is an UNSUBSCRIBE from `ROUND_TRIP`, which
        nobody subscribes to: no other client sees anything of it. Sent from this thread, as a publish is; `then`
        runs on the serving thread (or here)."""
        client = self._client
        if self._link is None or client is None or not self._connected:  # (`DrivenBus`: no thread reads answers)
            self._told(then, self._link is None and self._connected)
            return
        with self._inbox_lock:
            epoch = self._epoch
        rc, mid = client.unsubscribe(ROUND_TRIP)  # not under a lock of ours (see subscribe)
        if rc is not MQTTErrorCode.MQTT_ERR_SUCCESS or mid is None:
            self._told(then, False)
            return
        with self._inbox_lock:
            early = self._unsubacked.pop(mid, None)  # answered already, on the serving thread
            if early is None and epoch == self._epoch:
                self._trips[mid] = (epoch, then)
                return
        self._told(then, early == epoch)  # else lost meanwhile: `_trips_lost` ran already

    def _on_unsubscribe(
        self, _client: mqtt.Client, _userdata: Any, mid: int, _reasons: Any, _props: Properties | None
    ) -> None:
        with self._inbox_lock:
            trip = self._trips.pop(mid, None)
            current = self._epoch
            if trip is None:  # before `round_trip` had its message id
                if len(self._unsubacked) >= 64:
                    self._unsubacked.clear()
                self._unsubacked[mid] = current
        if trip is not None:
            self._told(trip[1], trip[0] == current)

    def _trips_lost(self) -> None:
        """The connection is gone: no `round_trip` sent on it will be answered."""
        with self._inbox_lock:
            trips, self._trips = self._trips, {}
            self._unsubacked.clear()
        for _epoch, then in trips.values():
            self._told(then, False)

    def _told(self, then: Callable[[bool], None], answered: bool) -> None:
        try:
            then(answered)
        except Exception:  # noqa: BLE001 - never let a hook kill the thread that serves connections
            log.exception("after a round trip to %s", self.address)

    def when_flushed(self, then: Callable[[], None]) -> None:
        """`then()` (on the serving thread, or here at once) once everything published so far is acknowledged
        (`flush` without a wait: for what must follow the broker's having it, node/admitted.py)."""
        with self._lock:
            if self._pending:
                self._flushed.append((set(self._pending), then))
                return
        then()

    def _on_publish(
        self, _client: mqtt.Client, _userdata: Any, mid: int, reason: ReasonCode, _props: Properties
    ) -> None:
        due: list[Callable[[], None]] = []
        topic: str | None = None
        with self._lock:
            if mid in self._unacked:  # a QoS 0 message written: nothing to wait for (and no QoS 1 one's ack)
                self._unacked.discard(mid)
            elif mid in self._pending:
                self._pending.discard(mid)
                topic = self._retained_inflight.pop(mid, None)
                for waits, _then in self._flushed:
                    waits.discard(mid)
                while self._flushed and not self._flushed[0][0]:  # (each waits for what the one before did)
                    due.append(self._flushed.pop(0)[1])
            else:
                self._acked_early.add(mid)
            self._lock.notify_all()
        for then in due:
            try:
                then()
            except Exception:  # noqa: BLE001 - never let a hook kill the thread that serves connections
                log.exception("after an acknowledgement from %s", self.address)
        if reason.is_failure:
            self._publish_refused(topic, reason)

    def _publish_refused(self, topic: str | None, reason: ReasonCode) -> None:
        """A message the broker did not take (an MQTT 5 PUBACK with a failure: its ACL, mostly), said once per
        topic (retained ones; the others once): a robot served under another robot's user published into the void
        with no word in the log."""
        key = topic or ""
        if key in self._refusals_said or len(self._refusals_said) > 64:
            return
        self._refusals_said.add(key)
        log.error(
            "MQTT broker %s refused a message of client %s%s: %s; the broker's ACL must let user %s write this "
            "robot's topics (docs/security.md)",
            self.address,
            self.client_id,
            f" on {topic}" if topic else "",
            reason.getName(),
            self.security.username or "(anonymous)",
        )

    def _on_subscribe(
        self, _client: mqtt.Client, _userdata: Any, mid: int, _reasons: list[ReasonCode], _props: Properties
    ) -> None:
        with self._lock:
            self._subacked.add(mid)
            self._lock.notify_all()

    # -- bus API -------------------------------------------------------------------------------------------

    def subscribe(self, pattern: str, handler: Handler, *, qos: int = 1, acks: bool = False) -> None:
        if not valid_filter(pattern):
            raise BusError(f"invalid topic filter {pattern!r}")
        check_qos(qos)
        with self._lock:
            known = pattern in self._qos and self._qos[pattern] >= qos
            self._qos[pattern] = max(qos, self._qos.get(pattern, 0))
            self._handlers.append((pattern, handler, acks))
            self._routes.clear()
        client = self._client
        if client is None or known or not self._connected:
            return  # subscribed on (re)connect
        epoch = self._epoch
        rc, mid = self._subscribe(client, [(pattern, qos)])  # never under self._lock: paho calls back holding its own
        if rc is not MQTTErrorCode.MQTT_ERR_SUCCESS or mid is None:
            return  # not connected after all: subscribed on reconnect
        with self._lock:
            self._await_suback(mid, pattern, epoch)

    def _subscribe(self, client: mqtt.Client, patterns: list[tuple[str, int]]) -> tuple[MQTTErrorCode, int | None]:
        """Subscribe to (filter, QoS) pairs; in MQTT 5 with retain-as-published, so that a message published
        retained keeps its flag also when it reaches this client already subscribed (a broker clears it
        otherwise, and a command published retained while the node is online looks live). MQTT 3.1.1 has no
        such option: there only the retained messages a new subscription finds are flagged. With `no_local`, also
        MQTT 5's no-local option: an edge node's command filters match the topics of its own property values."""
        if self.mqtt_version != "5" or not (self.retain_as_published or self.no_local):
            return client.subscribe(patterns)
        return client.subscribe(
            [
                (p, SubscribeOptions(qos=q, noLocal=self.no_local, retainAsPublished=self.retain_as_published))
                for p, q in patterns
            ]
        )

    def publish(self, topic: str, payload: bytes, *, retain: bool = False, qos: int = 1) -> None:
        if not valid_topic(topic):
            raise BusError(f"invalid topic {topic!r}")
        check_qos(qos)
        client = self._client
        if client is None:
            raise BusError("publish before connect")
        if self.refused is not None:
            raise BusError(f"not connected: this node stopped serving the MQTT broker at {self.address}")
        if not retain:
            self._send(client, topic, payload, retain, qos)
            return
        with self._retain_lock:  # the record and the message in the same order (see _republish)
            if payload:
                self._retained[topic] = (bytes(payload), qos)
            else:  # cleared: no longer ours to publish again
                self._retained.pop(topic, None)
            self._send(client, topic, payload, retain, qos)

    @contextlib.contextmanager
    def batch(self) -> Iterator[None]:
        """What this thread publishes inside goes out together at the end, in one write (an event and its WoT
        copy: thingbus.py): one wake-up of the broker, and of this process for the acknowledgements, not two.
        Nothing changes for a connection the serving loop does not serve (`DrivenBus`)."""
        link = self._link
        if link is None:
            yield
            return
        with link.batch():
            yield

    def _send(self, client: mqtt.Client, topic: str, payload: bytes, retain: bool, qos: int = 1) -> None:
        """Publish; at QoS 1 track the message id until its PUBACK (for `flush`)."""
        info = client.publish(topic, payload, qos=qos, retain=retain)  # not under self._lock (see subscribe)
        if info.rc not in (MQTTErrorCode.MQTT_ERR_SUCCESS, MQTTErrorCode.MQTT_ERR_NO_CONN):
            raise BusError(f"publishing on {topic} failed: {mqtt.error_string(info.rc)}")
        with self._lock:
            if qos == 0:
                # nothing to wait for. paho calls on_publish when it has written the message (dropped while
                # disconnected: at most once, no call); that call must not pass for the early PUBACK of a
                # later QoS 1 message with the same id
                if info.mid in self._acked_early:
                    self._acked_early.discard(info.mid)
                elif info.rc is MQTTErrorCode.MQTT_ERR_SUCCESS:
                    self._unacked.add(info.mid)
                return
            if info.mid in self._acked_early:
                self._acked_early.discard(info.mid)
            else:
                self._pending.add(info.mid)
                if retain:
                    self._retained_inflight[info.mid] = topic

    def flush(self, timeout: float) -> bool:
        if self.refused is not None:
            return False  # no broker will acknowledge what is pending
        link = self._link
        if link is not None and link.loop.on_thread():
            timeout = 0.0  # the serving thread reads the acknowledgements: it cannot wait for them
        with self._lock:
            return self._lock.wait_for(lambda: not self._pending, timeout)

    def close(self) -> None:
        client, self._client = self._client, None
        if client is None:
            return
        self._stop(client)  # a normal disconnect: the broker drops the will
        self._connected = False
        self._trips_lost()


def accepts_anonymous(
    address: BrokerAddress, tls: TlsOptions | None, *, timeout: float = 5.0, mqtt_version: str = "5"
) -> bool:
    """Whether the broker lets a client connect without credentials: no username, no password and no client
    certificate (`tls` gives the CA to trust the broker by; its certificate and key are left out).

    A TD that requires authentication is only kept if the broker enforces it: otherwise anyone who can reach
    the broker can command the robot or forge its feedback. A broker that identifies clients by certificate
    (mosquitto `require_certificate` + `use_identity_as_username`) refuses a client without one in the TLS
    handshake: that is refusing anonymous clients, and the node's own certificate must not hide it. An
    unreachable broker counts as refusing here; the node's own connection reports it.
    """
    anonymous_tls = None if tls is None else TlsOptions(ca_file=tls.ca_file)
    probe = MqttBus.sessionless(
        address,
        ConnectionSecurity(None, None, anonymous_tls, ()),
        "probe",
        mqtt_version=mqtt_version,
        connect_timeout=timeout,
    )
    probe.probe = True
    try:
        probe.connect()
    except BusError:
        return False
    probe.close()
    return True
