"""The bus as WoT consumers use it: an adapter between the engine and its bus (see `model/wot.py`).

The engine speaks the project's event envelope only. `ThingBus` wraps its bus and, for the robot it
serves:

* when the engine subscribes to the robot's command filters (`model.events.command_filters`), also subscribes
  to the WoT command filters (`model.wot.wot_command_filters`); a WoT message on the topic of an affordance
  (an action's input, a written value) is wrapped into the envelope event the engine expects (a fresh id and
  time, `source` "wot", `correlationId` → `correlation`, query/cancel `mission`) and handed to the engine as
  if it had arrived on the envelope topic (`Message.origin` says where it came from), so it is validated,
  refused or run by the same code; a message on any other topic there goes to the engine as it came (it
  drops what the node publishes there itself, and answers the rest `unknown-topic`). The WoT topics are
  subscribed at QoS 0: a WoT message carries no time, so one the broker kept for the node while it was away
  could not be told from a fresh one when it comes back (however old, it would run); at QoS 0 the broker does
  not queue it (mosquitto unless `queue_qos0_messages`), and the consumer, which still publishes at QoS 1 to
  the broker, gets no answer and can send it again;
* when the engine publishes an event, publishes it unchanged and, for a property value, a feedback, a state or
  an error meant for a WoT consumer, its WoT form on the WoT topic (the value alone, retained like the event;
  the outcome with `correlationId` and `mission` beside the payload). An error is meant for one when it
  answers a message that arrived on a WoT topic, or when a request's robot call failed (`busy`,
  `call-failed`, `unsupported`: news of the affordance, whoever asked); a refusal of an envelope event (its
  schema, id or time, its topic) is not: no WoT consumer sent it.

What cannot be wrapped (not JSON, not an object) goes to the engine as it came, so the engine answers it
with the error event a native client would get. Where a WoT message is refused for its data, the engine names
the members as the consumer sent them (`wot_problem`): `/procedure/goals/0/pose/x`, `/correlationId`.
"""

from __future__ import annotations

import contextlib
import json
import logging
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from hashlib import sha256
from typing import Any

from td2adaptor.model.events import ALL_ROBOTS, TOPIC_ROOT, EventCatalog, EventSpec, Kind, command_filters
from td2adaptor.model.wot import CORRELATION, WOT_LEVEL, takes_correlation, wot_command_filters, wot_topic
from td2adaptor.runtime.bus.bus import Bus, Handler, Message, when_flushed
from td2adaptor.runtime.events import MAX_ERRORS, Problem, loads, new_id, now_rfc3339, pointer, references

log = logging.getLogger("td2adaptor.runtime")

WOT_SOURCE = "wot"
#: error codes that refuse a message as it arrived (its topic, bytes, schema, id or time, retain flag): the
#: answer is for whoever sent it, on the tree it came on
REFUSALS = frozenset(
    {
        "invalid-json",
        "invalid-event",
        "too-large",
        "unknown-topic",
        "expired",
        "from-the-future",
        "id-reused",
        "no-id-or-time",
        "retained",
    }
)


class ThingBus:
    """`bus` with the WoT topics of robot `robot` served beside the envelope topics (a `Bus` itself)."""

    def __init__(
        self, bus: Bus, catalog: EventCatalog, robot: str, root: str = TOPIC_ROOT, *, correlation_ids: bool = False
    ) -> None:
        self.bus = bus
        self.correlation_ids = correlation_ids  # the event id is the consumer's correlationId (or none)
        self.catalog = catalog
        self.robot = robot
        self.root = root
        self._inbound = {s.topic(robot, root): s for s in catalog.inbound()}
        self._outbound = {s.topic(robot, root): s for s in catalog.specs if not s.kind.inbound}
        self._components = {s.affordance: s.component for s in catalog.specs if s.affordance}
        self._wot_inbound = {t: s for s in catalog.inbound() if (t := wot_topic(s, robot, root)) is not None}
        self._wot_tree = f"{root}/{robot}/{WOT_LEVEL}/"
        self._commands = set(command_filters(catalog, robot, root))
        self._wot_subscribed = False
        #: an event and its WoT copy written together, where the bus can (MqttBus.batch)
        self._batch: Callable[[], AbstractContextManager[Any]] = getattr(bus, "batch", contextlib.nullcontext)

    # -- Bus -----------------------------------------------------------------------------------------------

    def connect(self) -> None:
        self.bus.connect()

    def subscribe(self, pattern: str, handler: Handler, *, qos: int = 1, acks: bool = False) -> None:
        self.bus.subscribe(pattern, handler, qos=qos, acks=acks)
        if pattern not in self._commands or self._wot_subscribed:
            return  # the all-robots channel and anything else: envelope only
        self._wot_subscribed = True
        for wot in wot_command_filters(self.robot, self.root):
            self.bus.subscribe(wot, self._wot_handler(handler), qos=0)  # not queued while the node is away

    def _wot_handler(self, handler: Handler) -> Handler:
        """What hands a message on the WoT command filters to the engine's `handler`: on an affordance's topic
        wrapped into its envelope event, under the envelope topic; on any other, as it came."""

        def inbound(msg: Message) -> None:
            spec = self._wot_inbound.get(msg.topic)
            if spec is None:  # the node's own property values (dropped) or an unknown topic (answered)
                handler(Message(msg.topic, msg.payload, msg.retain, msg.topic))
                return
            native = spec.topic(self.robot, self.root)
            if msg.retain and not msg.payload:  # a retained command cleared: no message without input
                handler(Message(native, b"", msg.retain, msg.topic))
                return
            try:
                wrapped = self.wrap(spec, msg.payload)
            except Exception:  # a bug here must not cost the message its answer: the engine answers it as it is
                log.exception("could not wrap the WoT message on %s", msg.topic)
                wrapped = msg.payload
            handler(Message(native, wrapped, msg.retain, msg.topic))

        return inbound

    def publish(self, topic: str, payload: bytes, *, retain: bool = False, qos: int = 1) -> None:
        """`payload` and its WoT form, read back from it (an event resent from the ledger, a test's): the
        engine's own events come through `publish_event`, which does not parse what it just encoded."""
        self.bus.publish(topic, payload, retain=retain, qos=qos)
        spec = self._outbound.get(topic)
        if spec is None or spec.kind is Kind.STATUS or not payload:
            return
        try:
            event = json.loads(payload)
        except ValueError:
            return
        self._publish_wot(spec, event, retain, qos)

    def publish_event(
        self, topic: str, payload: bytes, event: Mapping[str, Any], *, retain: bool = False, qos: int = 1
    ) -> None:
        """`publish(topic, payload)` where `payload` is `event` encoded: the WoT form is made from `event`
        itself (the same text as from `payload` read back, without parsing it again). Both are written
        together (one send, `MqttBus.batch`)."""
        spec = self._outbound.get(topic)
        if spec is None or spec.kind is Kind.STATUS:
            self.bus.publish(topic, payload, retain=retain, qos=qos)
            return
        with self._batch():
            self.bus.publish(topic, payload, retain=retain, qos=qos)
            self._publish_wot(spec, event, retain, qos)

    def _publish_wot(self, spec: EventSpec, event: Any, retain: bool, qos: int) -> None:
        out = self.unwrap(spec, event)
        if out is not None:
            text = json.dumps(out[1], separators=(",", ":"), ensure_ascii=False, allow_nan=False)
            self.bus.publish(out[0], text.encode("utf-8"), retain=retain, qos=qos)

    def when_flushed(self, then: Callable[[], None]) -> None:
        """`then()` once the broker has everything published so far (the bus's `when_flushed`; at once on a bus
        without it)."""
        when_flushed(self.bus, then)

    def flush(self, timeout: float) -> bool:
        return self.bus.flush(timeout)

    @property
    def connected(self) -> bool:
        return self.bus.connected

    def close(self) -> None:
        self.bus.close()

    # -- translation ---------------------------------------------------------------------------------------

    def wrap(self, spec: EventSpec, raw: bytes) -> bytes:
        """The envelope event of a WoT message on `spec`'s WoT topic (`raw` itself when it is no JSON, or nested
        deeper than the parser follows: the engine then refuses it as it would the same envelope).

        Whatever the data holds is carried over as it is for the engine to judge, also what no event may hold
        (the engine refuses it, naming where): a lone surrogate stays its JSON escape, and a number no double
        holds (`1e400`) is written `Infinity`, which the engine reads as such (runtime/events.py)."""
        if not raw.strip():
            data: Any = {} if spec.kind is not Kind.WRITE else None
        else:
            try:
                data = loads(raw)
            except (ValueError, RecursionError):
                return raw  # the engine answers: invalid-json (or nested too deeply)
        try:
            return self._envelope(spec, data)
        except RecursionError:  # nested just short of what the parser follows: one level more is too many
            return raw

    def _envelope(self, spec: EventSpec, data: Any) -> bytes:
        event: dict[str, Any] = {"type": spec.kind.value, "affordance": spec.affordance, "robot": self.robot}
        event.update(id=new_id(), time=now_rfc3339(), source=WOT_SOURCE)
        if spec.kind is Kind.WRITE:
            event["payload"] = data
            return _encode(event)
        if self.correlation_ids:  # require_id_and_time: no correlationId, no id, and the engine refuses it
            del event["id"]
        if isinstance(data, dict) and takes_correlation(spec):
            data = dict(data)
            correlation = data.pop(CORRELATION, None)
            if correlation is not None:
                event["correlation"] = correlation  # the engine's schema checks it
                if self.correlation_ids and isinstance(correlation, str) and correlation:
                    long = len(correlation) > 128  # a lone surrogate hashes too: the engine refuses the correlation
                    event["id"] = (
                        sha256(correlation.encode("utf-8", "surrogatepass")).hexdigest() if long else correlation
                    )
        if spec.kind in (Kind.QUERY, Kind.CANCEL) and isinstance(data, dict):
            mission = data.pop("mission", None)
            if mission is not None:
                event["mission"] = mission
            if data:  # nothing else belongs there: the engine refuses it, naming the member
                event["payload"] = data
            return _encode(event)
        event["payload"] = data
        return _encode(event)

    def unwrap(self, spec: EventSpec, event: Any) -> tuple[str, Any] | None:
        """(WoT topic, data) of an event the engine published, or None when it has no WoT form."""
        if not isinstance(event, Mapping) or event.get("robot") != self.robot:
            return None
        if spec.kind is Kind.PROPERTY:
            topic = wot_topic(spec, self.robot, self.root)
            return None if topic is None else (topic, event.get("payload"))
        topic = wot_topic(spec, self.robot, self.root)
        payload = event.get("payload")
        if topic is None or not isinstance(payload, Mapping):
            return None
        answers_wot = str(payload.get("topic", "")).startswith(self._wot_tree)
        if spec.kind is Kind.ERROR and not answers_wot:
            if payload.get("code") in REFUSALS or event.get("affordance") not in self._components:
                return None  # it refused an envelope event (or concerns no affordance): no WoT consumer sent it
        data: dict[str, Any] = {}
        if spec.kind is Kind.ERROR and isinstance(event.get("affordance"), str):
            data["affordance"] = event["affordance"]
        if isinstance(event.get("correlation"), str):
            data[CORRELATION] = event["correlation"]
        if isinstance(event.get("mission"), int):
            data["mission"] = event["mission"]
        data.update(payload)
        if spec.kind is Kind.ERROR:  # the excerpt would be our envelope
            data.pop("event", None)
        if spec.kind is Kind.ERROR and not answers_wot:  # a robot call failed: name the affordance's WoT topic
            refused = self._inbound.get(str(data.get("topic")))
            wot = None if refused is None else wot_topic(refused, self.robot, self.root)
            if wot is not None:
                data["topic"] = wot
        return topic, data


def own_topics(catalog: EventCatalog, robot: str, root: str = TOPIC_ROOT) -> frozenset[str]:
    """Every topic the edge node of `robot` publishes events on, envelope and WoT: what arrives there on its
    command filters is its own (property values, the WoT error topic), never a command."""
    out = {s.topic(robot, root) for s in catalog.specs if not s.kind.inbound}
    out.update(t for s in catalog.specs if not s.kind.inbound and (t := wot_topic(s, robot, root)) is not None)
    return frozenset(out)


def wot_problem(spec: EventSpec, wrapped: bytes, problem: Problem) -> Problem:
    """`problem`, found in the envelope event `wrapped` of a WoT message on `spec`'s WoT topic, in the terms of
    the message its consumer sent: its members where the envelope has `/payload/...` (`/procedure/goals/0`),
    `/correlationId` for `/correlation`, each unexpected member of a query or cancel input by its name (the
    adapter carried them in a `payload` the event may not have)."""
    if not problem.errors:
        return problem
    try:
        event = loads(wrapped)
    except (ValueError, RecursionError):
        return problem
    if not isinstance(event, dict):
        return problem
    errors: list[tuple[str, str]] = []
    for path, message in problem.errors:
        errors.extend(_wot_errors(spec, event, path, message))
    errors = errors[:MAX_ERRORS]
    what = "value" if spec.kind is Kind.WRITE else "input"
    first = f"{errors[0][0] or '/'}: {errors[0][1]}"
    return Problem(problem.code, f"not a valid {what} of {spec.affordance} ({first})", tuple(errors))


def wot_references(raw: bytes) -> tuple[str | None, int | None]:
    """The `correlationId` and `mission` of a WoT message the engine refuses unwrapped (an unknown topic's),
    where they are of the kinds an answer may carry."""
    try:
        data = loads(raw)
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None, None
    if not isinstance(data, dict):
        return None, None
    return references({"correlation": data.get(CORRELATION), "mission": data.get("mission")})


def _wot_errors(spec: EventSpec, event: dict[str, Any], path: str, message: str) -> list[tuple[str, str]]:
    """One schema error of the envelope event `event` as errors of the WoT message it was wrapped from."""
    member, _, rest = path[1:].partition("/")
    below = f"/{rest}" if rest else ""
    if member == "correlation":
        return [(f"/{CORRELATION}{below}", message)]
    if member != "payload":  # `mission`, or a member the adapter set itself: named as it is
        return [(path, message)]
    if spec.kind in (Kind.QUERY, Kind.CANCEL) and not spec.goal_control and not rest:
        # the event may have no payload: it holds what the consumer sent beside mission and correlationId
        takes = f"{spec.affordance} takes only mission and {CORRELATION}"
        extra = event.get("payload")
        if not isinstance(extra, dict) or not extra:
            return [("", f"not an object: {takes}")]
        return [(pointer([name]), f"{pointer([name])[1:]!r} was unexpected: {takes}") for name in extra]
    return [(below, message)]  # the payload is the consumer's message (a goal's: its `goal` member is too)


def _encode(event: dict[str, Any]) -> bytes:
    """A wrapped event as the engine reads it: a lone surrogate written as its JSON escape (it cannot be UTF-8),
    so that the engine sees the string as the consumer sent it and refuses it."""
    text = json.dumps(event, separators=(",", ":"), ensure_ascii=False)
    return text.encode("utf-8", "backslashreplace")


def thing_bus(
    bus: Bus, catalog: EventCatalog, robot: str, root: str = TOPIC_ROOT, *, correlation_ids: bool = False
) -> Bus:
    """`bus` serving WoT consumers too (the all-robots id has no Thing of its own); `correlation_ids`
    (require_id_and_time): a WoT message's correlationId is its event id, and one without has none."""
    if robot == ALL_ROBOTS:
        return bus
    return ThingBus(bus, catalog, robot, root, correlation_ids=correlation_ids)
