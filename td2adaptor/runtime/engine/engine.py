"""The edge-node engine: events from the bus → robot calls → feedback on the bus.

Threads: the bus's own thread only queues messages; one dispatcher thread validates and routes them in
arrival order; each procedure mission runs in its own thread (start, then poll the linked query every
`poll_period`, a feedback event on every state change, exactly one terminal event, an overall
`mission_timeout`); queries, cancels of missions we do not follow, writes and plain calls run on a pool
of `CALL_WORKERS` threads (calls in flight at once); a property thread publishes subscribed values, at most
one per property and `property_period`.

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
  left in flight (its mission id known) and ends every other one `failed`, so each gets exactly one terminal
  event; an invoke sent again under its id is answered with the mission's last feedback event again (its
  current state, or its terminal event);
* feedback carries `correlation` (the requester's, else the invoke event's id) and `payload.seq` 1, 2, ...
"""

from __future__ import annotations

import json
import logging
import queue
import sqlite3
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from td2adaptor.model import Model, Procedure
from td2adaptor.model.events import ALL_ROBOTS, EventCatalog, EventSpec, Kind, build_catalog, command_filters
from td2adaptor.runtime.bus.bus import Bus, BusError, Message
from td2adaptor.runtime.bus.thingbus import WOT_SOURCE, own_topics, wot_problem, wot_references
from td2adaptor.runtime.config import RuntimeConfig
from td2adaptor.runtime.engine.goals import GoalRunner
from td2adaptor.runtime.engine.ledger import Ledger, Record
from td2adaptor.runtime.engine.missions import Mission, MissionTable
from td2adaptor.runtime.engine.outbox import Outbox
from td2adaptor.runtime.engine.replay import ReplayGuard, Verdict, digest, time_problem
from td2adaptor.runtime.engine.streams import PropertyStreams, streams
from td2adaptor.runtime.events import EventValidator, Problem, encode, envelope, references, salvage
from td2adaptor.runtime.ros.port import NoValue, PortError, RobotPort, StartResult
from td2adaptor.runtime.ros.procedures import ProcedureStatus, read
from td2adaptor.runtime.ros.words import INTERNAL, describe
from td2adaptor.runtime.workers import Workers

log = logging.getLogger("td2adaptor.runtime")

#: threads of the pool that runs queries, cancels, writes and plain calls: each waits for its robot call, so
#: as many calls can be in flight at once (to different components and robots; the robot answers in parallel)
CALL_WORKERS = 16

_DEFAULT_MISSION_PATH = ("state", "header", "id")


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


def _guard(config: RuntimeConfig) -> ReplayGuard:
    """The robot's replay guard: durable where the state directory can be written, else in memory."""
    path = config.ids_file
    try:
        return ReplayGuard(path, window=config.freshness_window, skew=config.clock_skew)
    except (OSError, sqlite3.Error) as exc:
        log.warning("event ids kept in memory only (%s: %s): a restart forgets them", path, exc)
        return ReplayGuard(None, window=config.freshness_window, skew=config.clock_skew)


def _ledger(config: RuntimeConfig) -> Ledger:
    """The robot's mission ledger, in the replay guard's file: durable where it can be written, else in memory."""
    path, keep = config.ids_file, config.freshness_window + config.clock_skew
    try:
        return Ledger(path, keep=keep)
    except (OSError, sqlite3.Error) as exc:
        log.warning("missions kept in memory only (%s: %s): a restart forgets them", path, exc)
        return Ledger(None, keep=keep)


def status_event(config: RuntimeConfig, model: Model, state: str) -> Message:
    """The retained online/offline status message (the offline one is the bus's will)."""
    event = envelope(
        Kind.STATUS,
        robot=config.robot,
        source=config.event_source,
        payload={"state": state, "thing": model.thing.title},
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
        self.validator = EventValidator(self.catalog)
        self.clock = clock
        self.td = td  # the robot's TD as the bus announces it on connecting: cleared on stop
        self.on_stop: list[Callable[[], None]] = []  # run first by stop() (e.g. leaving a TD directory)
        self.on_halt: list[Callable[[str], None]] = []  # told why, when the bus stops serving the broker (halt)
        self.failure: str | None = None  # why the bus stopped serving the broker, if it did
        self._inbox: queue.Queue[Message | None] = queue.Queue()
        self.guard = _guard(config)
        self.ledger = _ledger(config)
        self.missions = MissionTable()  # which mission each component runs (missions.py)
        self.outbox = Outbox(bus, config, self.catalog, self.ledger, self.missions)  # what we publish (outbox.py)
        self.stats = self.outbox.stats
        self._stopping = threading.Event()
        self._threads: list[threading.Thread] = []
        self._runners = Workers(f"td2adaptor-{config.robot}-mission")  # no thread start per invoke
        self._pool = ThreadPoolExecutor(max_workers=CALL_WORKERS, thread_name_prefix=f"td2adaptor-{config.robot}-call")
        self._goals = GoalRunner(port, config, self.missions, self.outbox, self._pool, self._stopping, clock)
        self._streams: PropertyStreams | None = None
        self._own = own_topics(self.catalog, config.robot, config.topic_root)  # never taken as commands

    # -- life cycle ----------------------------------------------------------------------------------------

    def start(self) -> None:
        """Subscribe, connect and start the worker threads: the robot's command filters (every command topic,
        also of an affordance it does not have: answered `unknown-topic`), and the all-robots channel's own
        command topics (where other robots' affordances are not unknown)."""
        root, robot = self.config.topic_root, self.config.robot
        for pattern in command_filters(self.catalog, robot, root):
            self.bus.subscribe(pattern, self._take)
        for spec in self.catalog.inbound():
            self.bus.subscribe(spec.topic(ALL_ROBOTS, root), self._inbox.put)
        self.bus.connect()
        self._recover()  # before any event is taken: a resent invoke finds what the last run left
        self._spawn(self._dispatch, "dispatch")
        properties = [s for s in self.catalog.specs if s.kind is Kind.PROPERTY]
        if self.config.property_period > 0 and properties:
            if self.config.property_mode == "message":  # one event per ROS message (runtime/engine/streams.py)
                self._streams = streams(self.outbox, port=self.port, model=self.model, specs=properties)
            if self._streams is not None:
                self._streams.start()
            else:
                self._spawn(self._properties, "properties")
        log.info("serving robot %s (namespace %s)", self.config.robot, self.config.ros_namespace)

    def _spawn(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=f"td2adaptor-{self.config.robot}-{name}", daemon=True)
        thread.start()
        self._threads.append(thread)

    def stop(self, timeout: float = 5.0) -> None:
        """Stop taking events, clear the TD, publish the offline status and disconnect. Missions go on on the
        robot."""
        if self._stopping.is_set():
            return
        self._stopping.set()
        for hook in self.on_stop:
            try:
                hook()
            except Exception:  # a hook must not keep the robot from going offline cleanly
                log.exception("while stopping robot %s", self.config.robot)
        self._inbox.put(None)
        if self._streams is not None:
            self._streams.stop()
        for m in self.missions.running():
            m.wake.set()
        for thread in self._threads:
            thread.join(timeout)
        self._pool.shutdown(wait=True, cancel_futures=True)
        for ended in self.missions.held():
            ended.wait(timeout)
        try:
            if self.td is not None:  # an empty retained message removes the TD from the broker
                self.bus.publish(self.td.topic, b"", retain=True)
            offline = status_event(self.config, self.model, "offline")
            self.bus.publish(offline.topic, offline.payload, retain=True)
            self.bus.flush(timeout)
        except BusError as exc:
            log.warning("could not publish the offline status: %s", exc)
        self.bus.close()
        self.guard.close()
        self.ledger.close()

    def halt(self, reason: str) -> None:
        """The bus stopped serving its broker for good (a reconnection failed the check every connection
        passes, see app.py): nothing more comes in; remember why and tell `on_halt` (`run` exits with it)."""
        if self.failure is not None:
            return
        self.failure = reason
        for hook in list(self.on_halt):
            try:
                hook(reason)
            except Exception:  # a hook must not keep the others from hearing it
                log.exception("while halting robot %s", self.config.robot)

    def idle(self) -> bool:
        """No queued event and no mission in progress (tests, benchmarks)."""
        return self._inbox.empty() and self.missions.idle()

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
        """A message on the robot's command filters (the bus's thread): queued, but what this node publishes
        there itself (property values, envelope and WoT, and the WoT error topic) is dropped at once."""
        if msg.topic not in self._own:
            self._inbox.put(msg)

    def _dispatch(self) -> None:
        while True:
            msg = self._inbox.get()
            if msg is None:
                return
            try:
                self._handle(msg)
            except Exception:  # a bug here must cost one event, not the process
                log.exception("internal error on %s", msg.topic)
                self.outbox.error("internal", INTERNAL, topic=msg.origin or msg.topic, raw=msg.payload)

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
            event, problem = self.validator.parse(spec, robot, msg.payload)
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
        verdict = self.guard.check(
            event_id if isinstance(event_id, str) else None,
            msg.topic,
            sent if isinstance(sent, str) else None,
            digest(event) if isinstance(event_id, str) else None,
        )
        if verdict is Verdict.DUPLICATE:
            self.outbox.count("duplicates")
            if spec.kind is Kind.INVOKE and isinstance(event_id, str):
                self._answer_again(event_id, msg.topic)
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
        component = self.model.component(spec.component or "")
        assert spec.affordance is not None
        procedure = component.procedure_of(spec.affordance)
        if any(a.name == spec.affordance for a in component.actions):
            if spec.kind is Kind.INVOKE:
                self._invoke(spec, Procedure(spec.affordance), event, msg.topic, goal=True)
            elif spec.kind is Kind.CANCEL:
                self._goals.cancel(spec, event)
            elif spec.kind is Kind.QUERY:
                self._pool.submit(self._goals.query, spec, event)
        elif spec.kind is Kind.INVOKE and procedure is not None and procedure.run == spec.affordance:
            self._invoke(spec, procedure, event, msg.topic)
        elif spec.kind is Kind.INVOKE:
            self._pool.submit(self._plain_call, spec, event, self._open("call", spec, event, msg.topic))
        elif spec.kind is Kind.QUERY and procedure is not None:
            self._pool.submit(self._query, spec, procedure, event)
        elif spec.kind is Kind.CANCEL and procedure is not None:
            self._cancel(spec, procedure, event)
        elif spec.kind is Kind.WRITE:
            self._pool.submit(self._write, spec, event)

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

    def _answer_again(self, event_id: str, topic: str) -> None:
        """An invoke sent again under its id (a redelivery, or a sender that lost track, also across a restart
        of this node): answered with the last feedback event of its mission again, as it was published."""
        record = self.ledger.latest(event_id, topic)
        if record is None or record.latest is None:  # its first feedback event, about to come, answers it
            log.info("invoke %s on %s again: its mission has no feedback yet", event_id, topic)
            return
        log.info("invoke %s on %s again: its last feedback event again (%s)", event_id, topic, record.state)
        self.outbox.count("answered-again")
        self.outbox.send(self.catalog.find(Kind.FEEDBACK, record.action), record.latest.encode("utf-8"))

    def _recover(self) -> None:
        """Finish what the last run of this node left (see ledger.py): follow each procedure mission again
        whose mission id the robot gave, publish a terminal event stored but maybe not sent, and end every
        other mission `failed`: whatever happened on the robot meanwhile, each gets one terminal event."""
        for record in self.ledger.pending():
            try:
                self._recover_one(record)
            except Exception:  # one mission's record must not keep the robot from being served
                log.exception("recovering %s mission %s", record.action, record.mission)
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
            log.info("%s mission %s: its terminal event again (the last run may not have sent it)", r.action, r.mission)
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
            log.info("following %s mission %s again (the edge node restarted)", r.action, r.mission)
            self.outbox.count("resumed")
            self._runners.submit(lambda: self._run_mission(m, ended, resume=True))
            return
        self.outbox.count("restart-failed")
        message = "the edge node restarted " + _restart_words(r, behind, self.config.mission_timeout)
        log.warning("%s mission %s: failed: %s", r.action, r.mission, message)
        self.outbox.finish(m, ProcedureStatus("failed", message=message, reason="unreachable"))

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
            what = f"{busy.action} mission {busy.mission_id}" if busy.mission_id is not None else busy.action
            message = f"{component} is busy with {what}; send a cancel event or wait for its terminal feedback"
            self.outbox.error("busy", message, topic=topic, affordance=procedure.run, correlation=correlation)
            mission.done = True
            status = ProcedureStatus("failed", message=message, reason="busy")
            self.outbox.feedback(mission, status, terminal=True)
            return
        self.outbox.count("missions")
        self._runners.submit(lambda: self._run_mission(mission, ended, goal))

    def _path(self, procedure: Procedure) -> tuple[str, ...]:
        return procedure.mission_id or _DEFAULT_MISSION_PATH

    def _run_mission(self, m: Mission, ended: threading.Event, goal: bool = False, resume: bool = False) -> None:
        try:
            if goal:
                self._goals.follow(m)
            elif resume:  # the robot runs it already (a restart of this node): follow it on
                self._poll(m, m.started + self.config.mission_timeout)
            else:
                self._follow(m)
        except Exception:  # the last line of defence: report, never crash
            log.exception("mission %s failed internally", m.action)
            self.outbox.finish(m, ProcedureStatus("failed", message=INTERNAL, reason="call-failed"))
        finally:
            self.missions.release(ended)
            ended.set()

    def _follow(self, m: Mission) -> None:
        cfg, port, proc = self.config, self.port, m.procedure
        deadline = m.started + cfg.mission_timeout
        refused = False
        try:
            started = port.start(m.component, m.action, m.payload, cfg.call_timeout)
        except PortError as exc:
            if exc.response is None:  # no answer: we cannot know whether it runs
                log.warning("%s: failed (%s): %s", m.action, exc.reason, _describe(exc))
                self.outbox.finish(m, ProcedureStatus("failed", message=_describe(exc), reason=exc.reason))
                return
            started, refused = StartResult(exc.response, None), True  # the robot answered, and refused
        except Exception as exc:
            log.warning("%s: failed: %s", m.action, _describe(exc))
            self.outbox.finish(m, ProcedureStatus("failed", message=_describe(exc), reason="call-failed"))
            return
        reading = read(started.response, proc, "run", _DEFAULT_MISSION_PATH)
        status = reading.status or ProcedureStatus("running", message="started")
        if reading.unmapped is not None:
            log.warning("%s: state value %r is not mapped: taken as started", m.action, reading.unmapped)
        if status.state != "failed" and (refused or _says_error(started.response)):
            status = ProcedureStatus("failed", status.result, status.message or _message(started.response))
        if status.state == "failed":  # refused by the robot: the id in its answer is not ours
            why = "answered with an error" if refused or _says_error(started.response) else "reported it failed"
            log.warning("%s: rejected: the robot %s: %s", m.action, why, status.message or "(no message)")
            self.outbox.finish(
                m, ProcedureStatus("failed", status.result, status.message, status.last_event, "rejected")
            )
            return
        m.mission_id = started.mission_id if started.mission_id is not None else status.mission_id
        if m.mission_id is None:
            log.warning("%s returned no mission id; following mission -1 (the robot's last one)", m.action)
        if status.terminal:
            self.outbox.finish(m, status)
            return
        self.outbox.feedback(m, status, terminal=False)
        if proc.query is None:
            self.outbox.finish(
                m, ProcedureStatus("finished", message="started; no query action links to this procedure")
            )
            return
        self._poll(m, deadline)

    def _poll(self, m: Mission, deadline: float) -> None:
        """Query a started mission every `poll_period` until its end (or the deadline, or a stop)."""
        cfg, port, proc = self.config, self.port, m.procedure
        assert proc.query is not None
        failures = 0
        while True:
            remaining = deadline - self.clock()
            m.wake.wait(max(0.0, min(cfg.poll_period, remaining)))
            m.wake.clear()
            if self._stopping.is_set():
                log.info("stopping: no longer following %s mission %s", m.action, m.mission_id)
                return
            if self._pending_cancels(m):
                return
            if self.clock() >= deadline:
                self._give_up(m)
                return
            mid = m.mission_id if m.mission_id is not None else -1
            try:
                response = _answer(port.query, m.component, proc.query, mid, cfg.call_timeout)
                reading = read(response, proc, "query", _DEFAULT_MISSION_PATH)
            except Exception as exc:
                failures += 1
                log.warning("query %d of %s mission %s failed: %s", failures, m.action, mid, _describe(exc))
                if failures >= cfg.max_query_failures:
                    message = f"the robot did not answer {failures} queries: {_describe(exc)}"
                    self.outbox.finish(m, ProcedureStatus("failed", message=message, reason="unreachable"))
                    return
                continue
            failures = 0
            current = reading.status
            if current is None:  # validate refuses such a query (ROS445); an unmapped value is no news
                log.warning("query of %s mission %s: no state in the answer (%r)", m.action, mid, reading.unmapped)
                continue
            if current.terminal:
                if current.state == "failed":
                    log.warning("%s mission %s: the robot reports it failed: %s", m.action, mid, current.message)
                self.outbox.finish(m, current)
                return
            if current.state != m.state:
                self.outbox.feedback(m, current, terminal=False)

    def _pending_cancels(self, m: Mission) -> bool:
        """Carry out cancel events for this mission; True when the mission ended."""
        requests = self.missions.take_cancels(m)
        proc = m.procedure
        for correlation in requests:
            mid = m.mission_id if m.mission_id is not None else -1
            if proc.cancel is None:
                self.outbox.error(
                    "unsupported",
                    f"{m.action} has no cancel action",
                    topic=self.catalog.find(Kind.INVOKE, m.action).topic(self.config.robot, self.config.topic_root),
                    affordance=m.action,
                    correlation=correlation,
                    mission=m.mission_id,
                )
                continue
            try:
                response = _answer(self.port.cancel, m.component, proc.cancel, mid, self.config.call_timeout)
                status = read(response, proc, "cancel", _DEFAULT_MISSION_PATH).status or _requested(m.state)
            except Exception as exc:
                self.outbox.error(
                    "call-failed",
                    f"cancelling {m.action} mission {mid} failed: {_describe(exc)}",
                    topic=self.catalog.find(Kind.CANCEL, proc.cancel).topic(self.config.robot, self.config.topic_root),
                    affordance=proc.cancel,
                    correlation=correlation,
                    mission=m.mission_id,
                )
                continue
            self.outbox.state(m.action, status, correlation, m.mission_id)
            if status.terminal:
                self.outbox.finish(m, status)
                return True
            if status.state != m.state:
                self.outbox.feedback(m, status, terminal=False)
        return False

    def _give_up(self, m: Mission) -> None:
        proc = m.procedure
        if proc.cancel is not None and m.mission_id is not None:
            try:
                self.port.cancel(m.component, proc.cancel, m.mission_id, self.config.call_timeout)
            except Exception as exc:
                log.warning("could not cancel timed-out %s mission %s: %s", m.action, m.mission_id, _describe(exc))
        message = f"no terminal state within the mission timeout of {self.config.mission_timeout:g} s"
        last = f" (last state: {m.state})" if m.state else ""
        self.outbox.finish(m, ProcedureStatus("failed", message=message + last, reason="timeout"))

    def _cancel(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any]) -> None:
        wanted = event.get("mission")
        correlation = event.get("correlation") or event.get("id")
        m = self.missions.add_cancel(
            spec.component or "",
            correlation,
            lambda m: m.action == procedure.run and wanted in (None, m.mission_id) and not m.done,
        )
        if m is not None:
            m.wake.set()
            return
        self._pool.submit(self._cancel_direct, spec, procedure, event)

    def _mission_for(self, procedure: Procedure, wanted: Any) -> int:
        if isinstance(wanted, int):
            return wanted
        return self.missions.mission_id(procedure.run)

    def _cancel_direct(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any]) -> None:
        self._ask(spec, procedure, event, cancel=True)

    def _query(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any]) -> None:
        self._ask(spec, procedure, event, cancel=False)

    def _ask(self, spec: EventSpec, procedure: Procedure, event: dict[str, Any], *, cancel: bool) -> None:
        """Answer a query (or a cancel of a mission we do not follow) with one state event."""
        correlation = event.get("correlation") or event.get("id")
        mid = self._mission_for(procedure, event.get("mission"))
        action = spec.affordance or ""
        try:
            call = self.port.cancel if cancel else self.port.query
            response = _answer(call, spec.component or "", action, mid, self.config.call_timeout)
        except Exception as exc:
            self.outbox.error(
                "call-failed",
                f"{action} of mission {mid} failed: {_describe(exc)}",
                topic=spec.topic(self.config.robot, self.config.topic_root),
                affordance=action,
                correlation=correlation,
                mission=mid if mid != -1 else None,
            )
            return
        status = read(response, procedure, "cancel" if cancel else "query", _DEFAULT_MISSION_PATH).status
        if status is None:
            status = _requested(None) if cancel else ProcedureStatus("running", message="no state in the answer")
        mission = status.mission_id if status.mission_id is not None else (mid if mid != -1 else None)
        self.outbox.state(procedure.run, status, correlation, mission)

    def _plain_call(self, spec: EventSpec, event: dict[str, Any], key: str | None = None) -> None:
        """A non-procedure action: one call, one terminal feedback with its output (also when it failed, if the
        robot answered: its response says how)."""
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
        try:
            output = dict(self.port.call(m.component, action, m.payload, self.config.call_timeout))
        except Exception as exc:
            reason = exc.reason if isinstance(exc, PortError) else "call-failed"
            log.warning("%s: failed (%s): %s", action, reason, _describe(exc))
            answer = exc.response if isinstance(exc, PortError) else None  # the robot answered, and said it failed
            status = ProcedureStatus("failed", message=_describe(exc), reason=reason)
            self.outbox.feedback(m, status, terminal=True, output=dict(answer) if answer is not None else None)
            return
        self.outbox.feedback(m, ProcedureStatus("finished"), terminal=True, output=output)

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

    def _properties(self) -> None:
        specs = [s for s in self.catalog.specs if s.kind is Kind.PROPERTY]
        last: dict[str, str] = {}
        complained: dict[str, float] = {}
        period = self.config.property_period
        while not self._stopping.wait(period):
            for spec in specs:
                name = spec.affordance or ""
                try:
                    value = self.port.read_property(spec.component or "", name, min(period, self.config.call_timeout))
                    text = json.dumps(value, sort_keys=True, allow_nan=False)
                except NoValue:
                    continue
                except Exception as exc:
                    if self.clock() - complained.get(name, -1e9) > 60:
                        complained[name] = self.clock()
                        log.warning("reading property %s failed: %s", name, _describe(exc))
                    continue
                if last.get(name) == text:
                    continue
                last[name] = text
                event = self.outbox.event(Kind.PROPERTY, value, affordance=name)
                self.outbox.publish(spec, event, retain=True, qos=self.config.property_qos)


def _answer(
    call: Callable[[str, str, int, float], Mapping[str, Any]], component: str, action: str, mission: int, timeout: float
) -> Mapping[str, Any]:
    """The robot's response to a query or cancel, also when the port raised because it says `error`."""
    try:
        return call(component, action, mission, timeout)
    except PortError as exc:
        if exc.response is None:
            raise
        return exc.response


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


def _requested(state: str | None) -> ProcedureStatus:
    """The answer to a cancel whose response carries no state: asked, the mission's end will tell."""
    return ProcedureStatus(state or "running", message="cancel requested")


def _message(response: Mapping[str, Any]) -> str:
    """The robot's words in a response without a procedure state (std_srvs' `message`)."""
    text = response.get("message")
    return text if isinstance(text, str) else ""


def _says_error(response: Mapping[str, Any]) -> bool:
    result = response.get("result")
    return isinstance(result, Mapping) and str(result.get("result", "")).lower() == "error"


def _describe(exc: BaseException) -> str:
    return describe(exc)  # user words, never class names (runtime/engine/words.py)
