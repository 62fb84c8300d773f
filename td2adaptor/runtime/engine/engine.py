"""The edge-node engine: events from the bus → robot calls → feedback on the bus.

Threads (loop.py; the same few for every robot of the process): the bus's thread only hands messages to the
process's engine loop; the loop validates and routes each robot's events one at a time, in arrival order, and
runs every procedure mission as a state machine (procedure.py: start, then a query each `poll_period` on a
timer, a feedback event on every state change, exactly one terminal event, an overall `mission_timeout`);
robot calls (a mission's start, queries and cancels; queries, cancels of missions we do not follow, writes,
plain calls and property samples) run on the process's call pool, at most `ROBOT_CALLS` of one robot at a
time; a sampled robot's properties are read each `property_period` (a timer) and published when changed.
ROS action goals are state machines on the loop too (goals.py), driven by the port's callbacks and timers.

Policies (documented in README of the generated events):
* one mission per component at a time: a second invoke is refused with an error event (`busy`) and a
  terminal `failed` feedback (`reason: busy`) for its correlation — never queued, never silently dropped;
* query and cancel use the mission id the robot returned; -1 (the robot's "last one") only when it gave none;
* every failure of a robot call becomes failure feedback or an error event; nothing ends the process;
* inbound events are fresh and unique (replay.py): an `id` seen before on the same topic with the same
  content (a QoS 1 redelivery, or a sender asking again) is run once, on another topic or with other content
  it is answered with an error, and an event older than the freshness window is answered with an error
  instead of run; ids are remembered across restarts;
* missions outlive the node (ledger.py): a restarted node follows again each procedure mission the last run
  left in flight (its mission id known) and each ROS action goal (by its goal id, goals.py `rejoin`) and ends
  every other one `failed`, so each gets exactly one terminal
  event; an invoke sent again under its id is answered with the mission's last feedback event again (its
  current state, or its terminal event);
* feedback carries `correlation` (the requester's, else the invoke event's id) and `payload.seq` 1, 2, ...
* a command is acknowledged to the broker only once it is taken: admitted (its id and mission written down) or
  answered. One the engine did not take (it stops: a hand-over, a stop) is not, so the broker delivers it again
  to whoever connects next with the robot's session (a restart, the next owner of a shared fleet).
"""

from __future__ import annotations

import json
import logging
import sqlite3
import threading
import time
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any, Final

from td2adaptor.model import Model, Procedure
from td2adaptor.model.events import ALL_ROBOTS, EventCatalog, EventSpec, Kind, build_catalog, command_filters
from td2adaptor.runtime.bus.bus import Bus, BusError, Message
from td2adaptor.runtime.bus.thingbus import WOT_SOURCE, own_topics, wot_problem, wot_references
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.context import RobotContext
from td2adaptor.runtime.engine.goals import GoalRunner
from td2adaptor.runtime.engine.ledger import Ledger, Record
from td2adaptor.runtime.engine.missions import Mission, MissionTable
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.engine.precheck import FastCheck
from td2adaptor.runtime.engine.procedure import DEFAULT_MISSION_PATH, ProcedureRunner, answer, answering, requested
from td2adaptor.runtime.engine.replay import ReplayGuard, Store, Verdict, digest, time_problem
from td2adaptor.runtime.engine.streams import PropertyStreams, streams
from td2adaptor.runtime.events import Problem, encode, envelope, references, salvage, validator_for
from td2adaptor.runtime.loop import Lane, Shared, Timer, acquire, release
from td2adaptor.runtime.ros.port import NoValue, PortError, QuickCall, RobotPort
from td2adaptor.runtime.ros.procedures import ProcedureStatus, read
from td2adaptor.runtime.ros.words import INTERNAL, describe

log = logging.getLogger("td2adaptor.runtime")

#: seconds a `busy` refusal waits for the robot to answer the start of the mission it names, so that it can
#: name it by its mission id (the robot answers in milliseconds; one that takes longer is named by its action)
BUSY_WAIT = 0.25
#: seconds between two looks at the ledger for the end another run owes to an invoke it took (`_answer_later`)
ANSWER_LOOK = 0.5
#: seconds an invoke whose end another run owes stays unacknowledged meanwhile (`_answer_later`): a run that stops
#: first leaves it to the robot's next connection; then it is acknowledged, and its end still sent when written
ANSWER_HOLD = 10.0


_REFUSALS = {
    Verdict.EXPIRED: "not run: sent at {time}, more than {window:g} s ago (the freshness window)",
    Verdict.FUTURE: "not run: sent at {time}, later than this node's clock allows",
    Verdict.BAD_TIME: "not run: its `time` {time!r} names no instant: {why}",
    Verdict.REUSED: "not run: event id {id!r} was already used by another event (on another topic or with other "
    "content); give every event an id of its own",
}
#: `id-reused` of a WoT message: its id is the consumer's correlationId (require_id_and_time)
_WOT_REUSED = (
    "not run: correlationId {id!r} was already used by another command (to another affordance or with other "
    "input); give every command a correlationId of its own"
)


_UNREAD: Final[Any] = object()  # the ledger not read yet for an event (a duplicate's row is read once)


def _state(config: RuntimeConfig) -> tuple[ReplayGuard, Ledger]:
    """The robot's replay guard and mission ledger, on one connection to the robot's SQLite file (`Store`):
    durable where the state directory can be written, else in memory."""
    path, keep = config.ids_file, config.freshness_window + config.clock_skew
    window, skew = config.freshness_window, config.clock_skew
    try:
        store = Store(path)
        try:
            return ReplayGuard(store, window=window, skew=skew), Ledger(store, keep=keep)
        except sqlite3.Error:  # a file that is no database of ours
            store.db.close()
            raise
    except (OSError, sqlite3.Error) as exc:
        log.warning("event ids and missions kept in memory only (%s: %s): a restart forgets them", path, exc)
        store = Store(None)
        return ReplayGuard(store, window=window, skew=skew), Ledger(store, keep=keep)


def status_event(config: RuntimeConfig, model: Model, state: str, **extra: Any) -> Message:
    """The retained online/offline status message (the offline one is the bus's will); `extra`: more members of
    its payload (the robot's presence and owner, runtime/node/status.py)."""
    event = envelope(
        Kind.STATUS,
        robot=config.robot,
        source=config.event_source,
        payload={"state": state, "thing": model.thing.title, **extra},
    )
    return Message(f"{config.topic_root}/{config.robot}/status", encode(event), retain=True)


class Engine:
    """Serves one robot: subscribe to its inbound topics and the all-robots ones, answer on its own."""

    def __init__(
        self,
        model: Model,
        port: RobotPort,
        bus: Bus,
        config: RuntimeConfig,
        *,
        catalog: EventCatalog | None = None,
        clock: Callable[[], float] = time.monotonic,
        td: Message | None = None,
    ) -> None:
        self.model = model
        self.port = port
        self.bus = bus
        self.config = config
        self.catalog = catalog or build_catalog(model)
        self.validator = validator_for(self.catalog)
        self.check = FastCheck(self.catalog, self.validator)  # valid events proved so in Rust (precheck.py)
        self.clock = clock
        self.td = td  # the robot's TD as the bus announces it on connecting: cleared on stop
        self.on_stop: list[Callable[[], None]] = []  # run first by stop() (e.g. leaving a TD directory)
        self.on_halt: list[Callable[[str], None]] = []  # told why, when the bus stops serving the broker (halt)
        self.failure: str | None = None  # why the bus stopped serving the broker, if it did
        self._ack: Callable[[], None] | None = None  # (the loop) the acknowledgement of the message being handled
        self.offline: Message | None = None  # the status stop() publishes (default: plain `offline`)
        #: (the loop) why an invoke of this affordance cannot reach the robot now (its ROS server is not there,
        #: runtime/node/presence.py), or None: such an invoke is answered at once instead of after a timeout
        self.absent: Callable[[EventSpec], str | None] | None = None
        #: (the loop) `kept(then)`: call `then()` once what was admitted so far is kept where the robot's next
        #: owner looks: at once (the id store and the ledger are written when admission returns); a shared fleet
        #: across hosts waits for the broker's acknowledgement of its admitted entries (node/admitted.py). A
        #: command is acknowledged to the broker then
        self.kept: Callable[[Callable[[], None]], None] = _at_once
        #: (the loop) `gate(go)` before a ROS action goal is sent, or None: `go(True)` (from any thread) once it
        #: may be sent, `go(False)` when it must not (the robot may be another process's by then, node/share.py)
        self.gate: Callable[[Callable[[bool], None]], None] | None = None
        #: what happened to the missions the robot's last owner left, the start of the terminal words of each one
        #: this run cannot follow on (a shared fleet's takeover says who took the robot over: node/share.py)
        self.restarted = "the edge node restarted"
        self.guard, self.ledger = _state(config)
        self.missions = MissionTable()  # which mission each component runs (missions.py)
        self.outbox = Outbox(bus, config, self.catalog, self.ledger, self.missions)  # what we publish (outbox.py)
        self.stats = self.outbox.stats
        self._stopping = threading.Event()
        self._closed = False  # (the loop's) no more inbound events are handled: the engine stops
        self._threads: list[threading.Thread] = []  # the process's engine loop, while this engine uses it
        self._shared: Shared | None = None  # the process's loop and call pool (loop.py), from start to stop
        self._lane: Lane | None = None  # this robot's share of the call pool
        self._ctx: RobotContext | None = None  # what the mission runners share (start)
        self._procedures: ProcedureRunner | None = None  # the procedure missions, on the loop (procedure.py)
        self._goals: GoalRunner | None = None  # the ROS action goals, on the loop (goals.py)
        self._streams: PropertyStreams | None = None
        self._sampler: Timer | None = None  # the next sampling of the properties (the loop's)
        self._sampling = False  # a sampling is under way on the pool (the next tick skips its turn)
        self._sampled = [s for s in self.catalog.specs if s.kind is Kind.PROPERTY]
        self._last_values: dict[str, str] = {}  # the sampling's (one at a time): each property's last value
        self._complained: dict[str, float] = {}  # the sampling's: when a property's read failure was logged
        self._counting = threading.Lock()
        self._queued = 0  # inbound messages handed to the loop, not handled yet (under _counting)
        self._early: list[Message] | None = []  # messages that came while the last run's missions were recovered
        self._own = own_topics(self.catalog, config.robot, config.topic_root)  # never taken as commands

    # -- life cycle ----------------------------------------------------------------------------------------

    def start(self) -> None:
        """Subscribe, connect and start serving on the process's engine loop: the robot's command filters (every
        command topic, also of an affordance it does not have: answered `unknown-topic`), and the all-robots
        channel's own command topics (where other robots' affordances are not unknown)."""
        root, robot = self.config.topic_root, self.config.robot
        shared = self._shared = acquire()
        self._threads = [shared.loop.thread]
        self._lane = Lane(shared.pool)
        ctx = RobotContext(
            self.port,
            self.config,
            self.missions,
            self.outbox,
            shared.loop,
            self._lane,
            self._stopping,
            self.clock,
            self.gate,
            self.port if isinstance(self.port, QuickCall) else None,
        )
        self._ctx = ctx
        self._procedures = ProcedureRunner(ctx)
        self._goals = GoalRunner(ctx)
        try:
            for pattern in command_filters(self.catalog, robot, root):  # acknowledged once taken (_dispatch)
                self.bus.subscribe(pattern, self._take, acks=True)
            for spec in self.catalog.inbound():
                self.bus.subscribe(spec.topic(ALL_ROBOTS, root), self._enter, acks=True)
            self.bus.connect()
        except BaseException:  # not serving: the loop and pool are not this engine's to keep
            self._shared, self._threads = None, []
            release(shared)
            raise
        shared.loop.call(self._recover)  # before any event is handled: a resent invoke finds what the last run left
        with self._counting:  # what came meanwhile, in order, then each as it comes
            early, self._early = self._early or [], None
            for msg in early:
                shared.loop.post(self._dispatch, msg)
        properties = self._sampled
        if self.config.property_period > 0 and properties:
            if self.config.property_mode == "message":  # one event per ROS message (runtime/engine/streams.py)
                self._streams = streams(self.outbox, port=self.port, model=self.model, specs=properties)
            if self._streams is not None:
                self._streams.start()
            else:
                shared.loop.post(self._sample_tick)
        log.info("serving robot %s (namespace %s)", self.config.robot, self.config.ros_namespace)

    def stop(self, timeout: float = 5.0, *, retire: str | None = None) -> None:
        """Stop taking events, clear the TD, publish the offline status and disconnect. Missions go on on the
        robot (and a restart of the node follows them again, ledger.py); with `retire` (the robot leaves the
        fleet, node/fleet.py) each mission still in flight ends with a terminal `failed` event that says it."""
        if self._stopping.is_set():
            return
        self._stopping.set()
        for hook in self.on_stop:
            try:
                hook()
            except Exception:  # a hook must not keep the robot from going offline cleanly
                log.exception("while stopping robot %s", self.config.robot)
        shared = self._shared
        if shared is not None:
            try:
                shared.loop.call(self._close, timeout)  # after the events queued so far
            except TimeoutError:  # the robot still goes offline cleanly
                log.warning("robot %s: the engine's loop did not take the stop in %g s", self.config.robot, timeout)
        if self._streams is not None:
            self._streams.stop()
        if self._lane is not None:
            self._lane.wait_idle(timeout)  # calls not started yet are skipped (missions' are made)
        for ended in self.missions.held():
            ended.wait(timeout)
        if retire is not None:
            for m in self.missions.running():
                self.outbox.finish(m, ProcedureStatus("failed", message=retire, reason="unreachable"))
        try:
            if self.td is not None:  # an empty retained message removes the TD from the broker
                self.bus.publish(self.td.topic, b"", retain=True)
            offline = self.offline or status_event(self.config, self.model, "offline")
            self.bus.publish(offline.topic, offline.payload, retain=True)
            if self.bus.connected:  # else no broker can acknowledge it: the will says offline, if it ever can
                self.bus.flush(timeout)
        except BusError as exc:
            log.warning("could not publish the offline status: %s", exc)
        self.bus.close()
        self.guard.close()
        self.ledger.close()
        if shared is not None:
            self._shared, self._threads = None, []
            release(shared)

    def _close(self) -> None:
        """(the loop) Handle no more inbound events, sample no more, leave every procedure mission to the robot."""
        self._closed = True
        if self._sampler is not None:
            self._sampler.cancel()
        if self._procedures is not None:
            self._procedures.stop()
        if self._goals is not None:
            self._goals.stop()

    def halt(self, reason: str) -> None:
        """The bus stopped serving its broker for good (a reconnection failed the check every connection
        passes, see app.py): nothing more comes in; remember why and tell `on_halt` (`run` exits with it)."""
        if self.failure is not None:
            return
        self.failure = reason
        self.outbox.abandon()
        for hook in list(self.on_halt):
            try:
                hook(reason)
            except Exception:  # a hook must not keep the others from hearing it
                log.exception("while halting robot %s", self.config.robot)

    def idle(self) -> bool:
        """No queued event and no mission in progress (tests, benchmarks)."""
        with self._counting:
            queued = self._queued
        return queued == 0 and self.missions.idle()

    def _submit(self, fn: Callable[..., None], *args: Any) -> None:
        """Run `fn(*args)` on this robot's lane of the call pool, unless the engine stops before its turn."""

        def task() -> None:
            if not self._stopping.is_set():
                fn(*args)

        assert self._lane is not None, "the engine is not started"
        self._lane.submit(task)

    # -- publishing ----------------------------------------------------------------------------------------

    def _refuse(
        self,
        code: str,
        message: str,
        msg: Message,
        spec: EventSpec,
        refs: tuple[str | None, int | None],
        errors: tuple[tuple[str, str], ...] = (),
    ) -> None:
        """Answer an inbound event that is not run (retained, stale, replayed, ...) with an error event carrying
        `refs`, its correlation and mission (and `errors`: the members at fault, as a schema error names them)."""
        self.outbox.count("refused")
        corr, mission = refs
        self.outbox.error(
            code,
            message,
            topic=msg.origin or msg.topic,  # where it arrived (a WoT topic: also answered on the WoT error topic)
            affordance=spec.affordance,
            correlation=corr,
            mission=mission,
            errors=errors,
        )

    # -- inbound -------------------------------------------------------------------------------------------

    def _take(self, msg: Message) -> None:
        """A message on the robot's command filters (the bus's thread): handed to the loop, but what this node
        publishes there itself (property values, envelope and WoT, and the WoT error topic) is dropped at once."""
        if msg.topic not in self._own:
            self._enter(msg)
        elif msg.ack is not None:
            msg.ack()

    def _enter(self, msg: Message) -> None:
        """(the bus's thread) Hand a message to the loop, after those before it (kept back while the last run's
        missions are recovered)."""
        with self._counting:
            self._queued += 1
            if self._early is not None:
                self._early.append(msg)
                return
        shared = self._shared
        if shared is not None:
            shared.loop.post(self._dispatch, msg)

    def _dispatch(self, msg: Message) -> None:
        """(the loop) One inbound message: validated, guarded and routed."""
        with self._counting:
            self._queued -= 1
        if self._closed:
            return  # not acknowledged: the broker delivers it again to the robot's session's next connection
        if msg.ack is not None and not self.bus.connected:
            # the connection it came on is gone, and its acknowledgement with it: the broker delivers it again to
            # the session's next connection, which may be another process's (a hung process of a shared fleet reads
            # what waited in its socket after the session moved). Taken here, the guard and ledger it shares on one
            # host would have that process take it for handled, and the answer would go on no connection
            return
        self._ack = msg.ack  # `_answer_again` may hold it back (`_answer_later`)
        try:
            self._handle(msg)
        except Exception:  # a bug here must cost one event, not the process
            log.exception("internal error on %s", msg.topic)
            self.outbox.error("internal", INTERNAL, topic=msg.origin or msg.topic, raw=msg.payload)
        ack, self._ack = self._ack, None
        if ack is not None:  # admitted or answered: the broker may forget it once that is kept
            self.kept(ack)

    def _handle(self, msg: Message) -> None:
        self.outbox.count("in")
        routed = self.catalog.route(msg.topic, self.config.topic_root)
        if routed is None:
            self._unknown(msg)
            return
        spec, robot = routed
        if robot not in (self.config.robot, ALL_ROBOTS):
            return
        if msg.retain and spec.kind.inbound:  # the broker would hand it over again at every reconnect
            if not msg.payload:  # the empty retained message that clears one: no command, nothing to answer
                self.outbox.count("cleared")
                return
            self._refuse(
                "retained",
                "not run: a command published with the retain flag would run again at every reconnect; publish "
                "commands without retain, and clear this one with an empty retained message on its topic",
                msg,
                spec,
                salvage(msg.payload),
            )
            return
        problem: Problem | None
        event: dict[str, Any] | None
        if len(msg.payload) > self.config.max_event_bytes:
            event, problem = None, Problem("too-large", f"events are limited to {self.config.max_event_bytes} bytes")
        else:
            event, problem = self.check.parse(spec, robot, msg.payload)
        if problem is not None or event is None:
            assert problem is not None
            self.outbox.count("invalid")
            corr, mission = salvage(msg.payload) if problem.code != "too-large" else (None, None)
            if msg.origin is not None:  # a WoT message: where its own data is at fault, as its consumer sent it
                problem = wot_problem(spec, msg.payload, problem)
            self.outbox.error(
                problem.code,
                problem.message,
                topic=msg.origin or msg.topic,
                raw=msg.payload,
                affordance=spec.affordance,
                correlation=corr,
                mission=mission,
                errors=problem.errors,
            )
            return
        event_id = event.get("id")
        sent = event.get("time")
        if self.config.require_id_and_time and not (isinstance(event_id, str) and isinstance(sent, str)):
            wot = event.get("source") == WOT_SOURCE
            self._refuse(
                "no-id-or-time",
                "not run: this node requires every inbound event to carry an id and a time "
                + ("(a WoT message: a correlationId) " if wot else "")
                + "(require_id_and_time), so that a replayed or long-queued command cannot run",
                msg,
                spec,
                references(event),
            )
            return
        content = digest(event) if isinstance(event_id, str) else None
        sent_text = sent if isinstance(sent, str) else None
        verdict = self.guard.check(event_id if isinstance(event_id, str) else None, msg.topic, sent_text, content)
        record = _UNREAD
        if verdict is Verdict.INHERITED and isinstance(event_id, str):
            record = self.ledger.latest(event_id, msg.topic) if spec.kind is Kind.INVOKE else None
            if self._never_taken(spec, record, event_id, msg):
                verdict = Verdict.NEW  # remembered by a run that stopped before taking it: it runs here
                self.guard.adopt(event_id, msg.topic, sent_text, content)
        if verdict in (Verdict.DUPLICATE, Verdict.INHERITED):
            self.outbox.count("duplicates")
            if spec.kind is Kind.INVOKE and isinstance(event_id, str):
                if record is _UNREAD:
                    record = self.ledger.latest(event_id, msg.topic)
                self._answer_again(event_id, msg.topic, record, inherited=verdict is Verdict.INHERITED)
            else:
                log.info("duplicate event %s on %s ignored", event_id, msg.topic)
            return
        if verdict is not Verdict.NEW:
            corr, mission = references(event)
            why = time_problem(sent) if verdict is Verdict.BAD_TIME and isinstance(sent, str) else None
            words = _WOT_REUSED if verdict is Verdict.REUSED and msg.origin is not None else _REFUSALS[verdict]
            self._refuse(
                verdict.value,
                words.format(id=event_id, time=sent, window=self.config.freshness_window, why=why),
                msg,
                spec,
                (corr or (event_id if isinstance(event_id, str) else None), mission),
                (("/time", why),) if why else (),
            )
            return
        if spec.kind is Kind.INVOKE and self.absent is not None:
            why = self.absent(spec)
            if why is not None:
                self._absent(spec, event, msg, why)
                return
        component = self.model.component(spec.component or "")
        assert spec.affordance is not None
        procedure = component.procedure_of(spec.affordance)
        if any(a.name == spec.affordance for a in component.actions):
            assert self._goals is not None
            if spec.kind is Kind.INVOKE:
                self._invoke(spec, Procedure(spec.affordance), event, msg.topic, goal=True)
            elif spec.kind is Kind.CANCEL:
                self._goals.cancel(spec, event)
            elif spec.kind is Kind.QUERY:
                self._goals.query(spec, event)
        elif spec.kind is Kind.INVOKE and procedure is not None and procedure.run == spec.affordance:
            self._invoke(spec, procedure, event, msg.topic)
        elif spec.kind is Kind.INVOKE:
            self.outbox.count("missions")  # a plain call is a mission too: its end is counted (metrics)
            self._plain(spec, event, self._open("call", spec, event, msg.topic))
        elif spec.kind is Kind.QUERY and procedure is not None:
            self._ask(spec, procedure, event, cancel=False)
        elif spec.kind is Kind.CANCEL and procedure is not None:
            self._cancel(spec, procedure, event)
        elif spec.kind is Kind.WRITE:
            self._submit(self._write, spec, event)

    def _unknown(self, msg: Message) -> None:
        """A message on a topic of the robot's command filters where no event is defined: answered
        `unknown-topic` (on a WoT topic: on the WoT error topic too). A retained one is not: nobody sends a
        command retained, it is someone's data (a value an earlier version of this robot's node published,
        handed over again at every connection), and an answer would repeat at every reconnect."""
        if msg.retain:
            self.outbox.count("unknown-retained")
            log.info("retained message on %s, where no event is defined: not answered", msg.topic)
            return
        message = "no event is defined on this topic: check it against the robot's Thing Description"
        refs: tuple[str | None, int | None] = (None, None)
        if len(msg.payload) <= self.config.max_event_bytes:  # its correlation, so that the sender knows its answer
            refs = salvage(msg.payload) if msg.origin is None else wot_references(msg.payload)
        self.outbox.error(
            "unknown-topic",
            message,
            topic=msg.origin or msg.topic,
            raw=msg.payload,
            correlation=refs[0],
            mission=refs[1],
        )

    # -- missions ------------------------------------------------------------------------------------------

    def _open(self, kind: str, spec: EventSpec, event: Mapping[str, Any], topic: str) -> str:
        """Put an invoke the node takes in the ledger (see ledger.py); its key."""
        event_id = event.get("id")
        return self.ledger.open(
            event_id=event_id if isinstance(event_id, str) else None,
            topic=topic,
            kind=kind,
            component=spec.component or "",
            action=spec.affordance or "",
            correlation=event.get("correlation") or event.get("id"),
        )

    def _never_taken(self, spec: EventSpec, record: Record | None, event_id: str, msg: Message) -> bool:
        """An id another run of this node remembered (replay.py, `inherited`): was the command never taken?
        An invoke was taken once the ledger has it (`record`: its row is opened before anything reaches ROS); a
        query or a cancel is answered again whatever happened (asking twice changes nothing). A property write
        is not known to have been written or not: it is not written again. A command never taken becomes this
        run's."""
        if spec.kind is Kind.INVOKE:
            taken = record is not None
        else:
            taken = spec.kind not in (Kind.QUERY, Kind.CANCEL)
        if not taken:
            log.info(
                "event %s on %s: an earlier run remembered it and stopped before taking it: taken now",
                event_id,
                msg.topic,
            )
        return not taken

    def _answer_again(self, event_id: str, topic: str, record: Record | None, *, inherited: bool = False) -> None:
        """An invoke sent again under its id (a redelivery, or a sender that lost track, also across a restart
        of this node): answered with the last feedback event of its mission (`record`, the ledger's) again, as
        it was published. One another live run took (`inherited`: a process of a shared fleet on this host) and
        has not ended yet is also answered from here with its end, once that run wrote it (`_answer_later`)."""
        follow = inherited and record is not None and record.phase == "running" and not self._follows(record.key)
        if record is None or record.latest is None:  # its first feedback event, about to come, answers it
            log.info("invoke %s on %s again: its mission has no feedback yet", event_id, topic)
        else:
            log.info("invoke %s on %s again: its last feedback event again (%s)", event_id, topic, record.state)
            self.outbox.count("answered-again")
            self.outbox.send(self.catalog.find(Kind.FEEDBACK, record.action), record.latest.encode("utf-8"))
        if follow:
            ack, self._ack = self._ack, None
            now = time.monotonic()
            self._answer_later(event_id, topic, now + self.config.mission_timeout, ack, now + ANSWER_HOLD)

    def _answer_later(
        self,
        event_id: str,
        topic: str,
        until: float,
        ack: Callable[[], None] | None = None,
        hold: float = 0.0,
    ) -> None:
        """(the loop) An invoke another run took before this one got it: this run holds the robot's session now,
        so that run's answer may go on no connection (a hung process that resumed took it from a connection whose
        session had moved, just before it learnt so): its end is sent from here once the ledger has it (a second
        copy, under the same event id, when that run's did reach the broker). Looked for until `until`. The
        invoke's `ack` waits until then, or `hold` at most: a run that stops first (the robot handed over) leaves
        the invoke to the robot's next connection, which answers it in turn."""
        if self._closed:
            return  # not acknowledged (unless `hold` is over): the next connection gets it again
        record = self.ledger.latest(event_id, topic)
        done = record is None or self._follows(record.key)  # else this run follows it now: its end is its own
        if not done and record is not None and record.latest is not None and record.phase != "running":
            self._answer_again(event_id, topic, record)
            done = True
        shared = self._shared
        if not done and (shared is None or time.monotonic() >= until):
            log.warning("invoke %s on %s: the run that took it wrote no end for it", event_id, topic)
            done = True
        if ack is not None and (done or time.monotonic() >= hold):
            self.kept(ack)
            ack = None
        if not done and shared is not None:
            shared.loop.call_later(ANSWER_LOOK, self._answer_later, event_id, topic, until, ack, hold)

    def _follows(self, key: str) -> bool:
        """Whether this run follows the mission of ledger row `key` (it runs, or its recovery took it up)."""
        return any(m.key == key for m in self.missions.running())

    def _recover(self) -> None:
        """Finish what the last run of this node left (see ledger.py): follow each procedure mission again
        whose mission id the robot gave, and each ROS action goal the server accepted by its id, publish a
        terminal event stored but maybe not sent, and end every other mission `failed`: whatever happened on the
        robot meanwhile, each gets one terminal event."""
        for record in self.ledger.pending():
            try:
                self._recover_one(record)
            except Exception:  # one mission's record must not keep the robot from being served
                log.exception("recovering %s %s", record.action, _which(record))
                self.ledger.done(record.key)

    def _recover_one(self, r: Record) -> None:
        try:
            spec = self.catalog.find(Kind.FEEDBACK, r.action)
            component = self.model.component(r.component)
        except (StopIteration, KeyError):  # the TD changed between the two runs
            log.warning("a %s mission of the last run is not in this TD: forgotten", r.action)
            self.ledger.done(r.key)
            return
        if r.phase == "ending" and r.latest is not None:  # maybe not sent before the node died: again
            log.info("%s %s: its terminal event again (the last run may not have sent it)", r.action, _which(r))
            self.outbox.send(spec, r.latest.encode("utf-8"))
            self.ledger.done(r.key)
            return
        procedure = (component.procedure_of(r.action) if r.kind == "procedure" else None) or Procedure(r.action)
        behind = max(0.0, time.time() - r.started)
        seq = max(r.seq, r.reserved)
        m = Mission(r.component, r.action, procedure, r.correlation, {}, self.clock() - behind)
        m.mission_id, m.goal, m.state, m.seq, m.reserved, m.key = r.mission, r.goal, r.state, seq, seq, r.key
        ended = threading.Event()
        follow = r.kind == "procedure" and r.state is not None and r.mission is not None
        follow = follow and procedure.query is not None and behind < self.config.mission_timeout
        follow = follow and self.missions.claim(m, ended) is None  # only when the component is free
        if follow:
            log.info("following %s mission %s again (%s)", r.action, r.mission, self.restarted)
            self.outbox.count("resumed")
            assert self._procedures is not None
            self._procedures.resume(m, ended)
            return
        if self._rejoin(r, m, behind, ended):
            return
        self.outbox.count("restart-failed")
        message = f"{self.restarted} {_restart_words(r, behind, self.config.mission_timeout)}"
        log.warning("%s %s: failed: %s", r.action, _which(r), message)
        self.outbox.finish(m, ProcedureStatus("failed", message=message, reason="unreachable"))

    def _rejoin(self, r: Record, m: Mission, behind: float, ended: threading.Event) -> bool:
        """Follow on a ROS action goal the last run left (the server accepted it: its id is known), by its id,
        when the port can and its component is free; whether it is followed (goals.py `rejoin`)."""
        goals = self._goals
        if r.kind != "goal" or r.goal is None or r.state is None or behind >= self.config.mission_timeout:
            return False
        if goals is None or not goals.can_rejoin() or self.missions.claim(m, ended) is not None:
            return False
        log.info("following %s goal %s again (%s)", r.action, r.goal, self.restarted)
        self.outbox.count("rejoined")
        goals.rejoin(m, ended, self.restarted)
        return True

    def _invoke(
        self, spec: EventSpec, procedure: Procedure, event: dict[str, Any], topic: str, *, goal: bool = False
    ) -> None:
        component = spec.component or ""
        correlation = event.get("correlation") or event.get("id")
        mission = Mission(component, procedure.run, procedure, correlation, event.get("payload") or {}, self.clock())
        ended = threading.Event()
        busy = self.missions.claim(mission, ended)
        if busy is not None and correlation is not None and busy.correlation == correlation:
            self.outbox.count("duplicates")  # a redelivery of the invoke we are following (sent without an id)
            log.info("invoke %s for mission %s already in progress: ignored", correlation, busy.mission_id)
            return
        mission.key = self._open("goal" if goal else "procedure", spec, event, topic)
        if busy is not None:
            mission.done = True
            refuse = partial(self._busy, busy, mission, topic)
            if self._procedures is None or not self._procedures.when_started(busy, refuse, BUSY_WAIT):
                refuse()
            return
        self.outbox.count("missions")
        if goal:
            assert self._goals is not None
            self._goals.start(mission, ended)
            return
        assert self._procedures is not None
        self._procedures.start(mission, ended)

    def _absent(self, spec: EventSpec, event: dict[str, Any], msg: Message, why: str) -> None:
        """An invoke of an action whose ROS server is not there: not sent (it would wait for the server until
        `call_timeout`), answered at once with an `absent` error and a terminal `failed` feedback (`reason:
        unreachable`), as a call that found no server would end."""
        action = spec.affordance or ""
        correlation = event.get("correlation") or event.get("id")
        self.outbox.count("absent")
        topic = msg.origin or msg.topic
        self.outbox.error("absent", why, topic=topic, affordance=action, correlation=correlation)
        component = self.model.component(spec.component or "")
        procedure = component.procedure_of(action)
        kind = "goal" if any(a.name == action for a in component.actions) else "call"
        kind = "procedure" if procedure is not None and procedure.run == action else kind
        mission = Mission(spec.component or "", action, procedure or Procedure(action), correlation, {}, self.clock())
        mission.done = True
        mission.key = self._open(kind, spec, event, msg.topic)
        self.outbox.feedback(mission, ProcedureStatus("failed", message=why, reason="unreachable"), terminal=True)

    def _busy(self, busy: Mission, mission: Mission, topic: str) -> None:
        """Refuse `mission`: its component runs `busy`, named by its mission id when the robot gave one (a refusal
        that comes while `busy` is being started is made once the robot answered the start)."""
        what = f"{busy.action} mission {busy.mission_id}" if busy.mission_id is not None else busy.action
        message = f"{mission.component} is busy with {what}; send a cancel event or wait for its terminal feedback"
        self.outbox.error("busy", message, topic=topic, affordance=mission.action, correlation=mission.correlation)
        status = ProcedureStatus("failed", message=message, reason="busy")
        self.outbox.feedback(mission, status, terminal=True)

    def _cancel(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any]) -> None:
        wanted = event.get("mission")
        correlation = event.get("correlation") or event.get("id")
        m = self.missions.add_cancel(
            spec.component or "",
            correlation,
            lambda m: m.action == procedure.run and wanted in (None, m.mission_id) and not m.done,
        )
        if m is not None:
            assert self._procedures is not None
            self._procedures.poke(m)
            return
        self._ask(spec, procedure, event, cancel=True)

    def _mission_for(self, procedure: Procedure, wanted: Any) -> int:
        if isinstance(wanted, int):
            return wanted
        return self.missions.mission_id(procedure.run)

    def _ask(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any], *, cancel: bool) -> None:
        """(the loop) A query (or a cancel of a mission we do not follow): which mission it is about, then the
        call, answered with one state event: sent from here when the port can do it without a waiting thread
        (`QuickCall`: the answer is published on the port's thread), else on the pool."""
        mid = self._mission_for(procedure, event.get("mission"))
        ctx = self._ctx
        if ctx is not None and ctx.quick is not None:
            send = ctx.quick.try_cancel if cancel else ctx.quick.try_query
            told = answering(partial(self._asked_then, spec, procedure, event, mid, cancel))
            component, action, timeout = spec.component or "", spec.affordance or "", self.config.call_timeout
            if ctx.send_quick(partial(send, component, action, mid, timeout), told):
                return
        self._submit(self._asked, spec, procedure, event, mid, cancel)

    def _asked(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any], mid: int, cancel: bool) -> None:
        try:
            call = self.port.cancel if cancel else self.port.query
            response, error = (
                answer(call, spec.component or "", spec.affordance or "", mid, self.config.call_timeout),
                None,
            )
        except Exception as exc:
            response, error = None, exc
        self._asked_then(spec, procedure, event, mid, cancel, response, error)

    def _asked_then(
        self,
        spec: EventSpec,
        procedure: Procedure,
        event: dict[str, Any],
        mid: int,
        cancel: bool,
        response: Any,
        error: BaseException | None,
    ) -> None:
        """A query's (cancel's) answer, or why none came: one state event, or an error event."""
        correlation = event.get("correlation") or event.get("id")
        action = spec.affordance or ""
        if error is not None:
            self.outbox.error(
                "call-failed",
                f"{action} of mission {mid} failed: {_describe(error)}",
                topic=spec.topic(self.config.robot, self.config.topic_root),
                affordance=action,
                correlation=correlation,
                mission=mid if mid != -1 else None,
            )
            return
        status = read(response, procedure, "cancel" if cancel else "query", DEFAULT_MISSION_PATH).status
        if status is None:
            status = requested(None) if cancel else ProcedureStatus("running", message="no state in the answer")
        mission = status.mission_id if status.mission_id is not None else (mid if mid != -1 else None)
        self.outbox.state(procedure.run, status, correlation, mission)

    def _plain(self, spec: EventSpec, event: dict[str, Any], key: str | None = None) -> None:
        """(the loop) A non-procedure action: one call, one terminal feedback with its output (also when it
        failed, if the robot answered: its response says how); sent from here when the port can do it without a
        waiting thread (`QuickCall`), else on the pool."""
        action = spec.affordance or ""
        m = Mission(
            spec.component or "",
            action,
            Procedure(action),
            event.get("correlation") or event.get("id"),
            event.get("payload") or {},
            self.clock(),
            done=True,
            key=key,
        )
        ctx = self._ctx
        if ctx is not None and ctx.quick is not None:
            send = partial(ctx.quick.try_call, m.component, action, m.payload, self.config.call_timeout)
            if ctx.send_quick(send, partial(self._called, m)):
                return
        self._submit(self._plain_call, m)

    def _plain_call(self, m: Mission) -> None:
        try:
            output, error = self.port.call(m.component, m.action, m.payload, self.config.call_timeout), None
        except Exception as exc:
            output, error = None, exc
        self._called(m, output, error)

    def _called(self, m: Mission, output: Any, error: BaseException | None) -> None:
        """A plain call's answer, or why none came: its terminal feedback."""
        if error is not None:
            reason = error.reason if isinstance(error, PortError) else "call-failed"
            log.warning("%s: failed (%s): %s", m.action, reason, _describe(error))
            answer = error.response if isinstance(error, PortError) else None  # the robot answered, and said it failed
            status = ProcedureStatus("failed", message=_describe(error), reason=reason)
            self.outbox.feedback(m, status, terminal=True, output=dict(answer) if answer is not None else None)
            return
        self.outbox.feedback(m, ProcedureStatus("finished"), terminal=True, output=dict(output))

    def _write(self, spec: EventSpec, event: dict[str, Any]) -> None:
        name = spec.affordance or ""
        try:
            self.port.write_property(spec.component or "", name, event.get("payload"))
        except Exception as exc:
            self.outbox.error(
                "call-failed",
                f"writing {name} failed: {_describe(exc)}",
                topic=spec.topic(self.config.robot, self.config.topic_root),
                affordance=name,
                correlation=event.get("correlation") or event.get("id"),
            )

    # -- properties ----------------------------------------------------------------------------------------

    def _sample_tick(self) -> None:
        """(the loop) Every `property_period`: sample the properties on the pool, unless the last sampling is
        still under way (a slow robot's reads take their turn, they are not queued up)."""
        if self._closed:
            return
        if not self._sampling:
            self._sampling = True
            self._submit(self._sample)
        assert self._shared is not None
        self._sampler = self._shared.loop.call_later(self.config.property_period, self._sample_tick)

    def _sample(self) -> None:
        """(a pool thread) Read every property; publish those whose value changed, retained."""
        period = self.config.property_period
        try:
            for spec in self._sampled:
                name = spec.affordance or ""
                try:
                    value = self.port.read_property(spec.component or "", name, min(period, self.config.call_timeout))
                    text = json.dumps(value, sort_keys=True, allow_nan=False)
                except NoValue:
                    continue
                except Exception as exc:
                    if self.clock() - self._complained.get(name, -1e9) > 60:
                        self._complained[name] = self.clock()
                        log.warning("reading property %s failed: %s", name, _describe(exc))
                    continue
                if self._last_values.get(name) == text:
                    continue
                self._last_values[name] = text
                event = self.outbox.event(Kind.PROPERTY, value, affordance=name)
                self.outbox.publish(spec, event, retain=True, qos=self.config.property_qos)
        finally:
            self._sampling = False


def _at_once(then: Callable[[], None]) -> None:
    then()


def _restart_words(r: Record, behind: float, timeout: float) -> str:
    """Why a mission the last run left cannot be followed on (`behind` seconds after it started), and that its
    outcome is unknown."""
    if r.state is None:
        return "before the robot answered this invoke: whether the robot runs it is unknown"
    if r.kind == "goal":
        return f"while it followed this goal ({r.goal}): its outcome is unknown (it may go on on the robot)"
    if r.kind == "call":
        return "during this call: its outcome is unknown"
    if r.mission is None:
        return "while it followed this mission: its outcome is unknown (the robot gave no mission id to ask it about)"
    if behind >= timeout:  # it would have timed out meanwhile (and its id may name another mission by now)
        return f"after this mission's timeout of {timeout:g} s had passed: its outcome is unknown"
    return "while it followed this mission: its outcome is unknown"


def _which(r: Record) -> str:
    """How the log names a mission the last run left: a goal has no mission id ("mission None" said nothing)."""
    if r.kind == "goal" and r.goal:
        return f"goal {r.goal}"
    if r.mission is not None:
        return f"mission {r.mission}"
    return f"invoke {r.correlation or r.event_id or '(without id)'}"


def _describe(exc: BaseException) -> str:
    return describe(exc)  # user words, never class names (runtime/engine/words.py)
