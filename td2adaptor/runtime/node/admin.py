"""Admin requests on the bus: add a robot to a running fleet, or remove one (docs/fleet.md, "Admin requests").

The process listens on `<root>/.fleet/<fleet>/request` (a level no robot id can be: robot ids never start
with a dot) and answers every request it can read on `<root>/.fleet/<fleet>/answer`, its `correlation` the
request's `id`. Two locks keep a stranger out: the broker's ACL (the events backend's `mosquitto.acl` lets only
admin users publish requests), and the request itself, signed with the fleet's admin key (`fleet_admin_key`,
HMAC-SHA256 of the request without its `signature`, in `canonical` form), fresh (`time` within the freshness
window) and new (its `id` not seen before). Without a key the fleet has no admin, and every request is
refused. The requests are carried out one at a time on a thread of their own, never on the bus's.

In a fleet shared by several processes (`run --share`, share.py) every process reads every request, and one
answers and carries it out: the live member whose node id sorts first (the others check the request too, so a
replay is known to whoever answers next). An added robot is retained as an entry on the broker
(`<root>/.fleet/<fleet>/robots/<robot>`), which every member reads: the share gives it to one of them, and the
answer comes once its owner serves it and names that process. Removing it clears the entry: its owner retires it.
Only robots added this way can be removed (the others come from a fleet file or the ROS graph).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import logging
import queue
import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from td2adaptor.model.events import ALL_ROBOTS, ROBOT_ID
from td2adaptor.runtime.bus.bus import Bus, BusError, Message
from td2adaptor.runtime.config import ConfigError, RuntimeConfig
from td2adaptor.runtime.engine.replay import parse_time
from td2adaptor.runtime.events import new_id, now_rfc3339
from td2adaptor.runtime.node.fleet import Fleet, FleetError

if TYPE_CHECKING:
    from td2adaptor.runtime.node.share import Share

log = logging.getLogger("td2adaptor.runtime.fleet")

ADMIN_LEVEL = ".fleet"
MAX_REQUEST_BYTES = 16384
OPS = ("add", "remove")
#: seconds a shared fleet's answering member waits for a robot it added to be served (or one it removed to stop)
SHARED_WAIT = 15.0


def admin_topics(root: str, fleet: str) -> tuple[str, str]:
    """(request topic, answer topic) of a fleet's admin requests."""
    return f"{root}/{ADMIN_LEVEL}/{fleet}/request", f"{root}/{ADMIN_LEVEL}/{fleet}/answer"


def canonical(request: Mapping[str, Any]) -> bytes:
    """The bytes a request's signature covers: the request without `signature`, as JSON with sorted keys and
    no blanks (`json.dumps(..., sort_keys=True, separators=(",", ":"), ensure_ascii=False)`, UTF-8)."""
    body = {k: v for k, v in request.items() if k != "signature"}
    return json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


#: what an unsigned request is told a signature is
SIGNATURE = "the hex HMAC-SHA256 of the request without it, under the fleet's admin key"


def sign(request: Mapping[str, Any], key: str) -> dict[str, Any]:
    """`request` with its `signature` (hex HMAC-SHA256 of `canonical(request)` under `key`)."""
    mac = hmac.new(key.encode("utf-8"), canonical(request), hashlib.sha256).hexdigest()
    return {**request, "signature": mac}


class Refused(Exception):
    """A request that is answered without being carried out: `code` and the words of the answer."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


class Admin:
    """Takes the admin requests of one fleet from `bus` and carries them out on `fleet` (module docstring).
    `make_config(robot, namespace)` is the configuration a robot added this way gets (the fleet's shared
    settings, config.load_defaults)."""

    def __init__(
        self,
        fleet: Fleet,
        bus: Bus,
        *,
        name: str,
        root: str,
        key: str | None,
        make_config: Callable[[str, str | None], RuntimeConfig],
        freshness_window: float,
        clock_skew: float,
        share: Share | None = None,
    ) -> None:
        self.fleet = fleet
        self.share = share  # `run --share`: the requests change the shared fleet (module docstring)
        self.bus = bus
        self.name = name
        self.request_topic, self.answer_topic = admin_topics(root, name)
        self.key = key
        self.make_config = make_config
        self.freshness_window = freshness_window
        self.clock_skew = clock_skew
        self.answered: dict[str, int] = {}  # answers by code (tests, the log)
        self._seen: dict[str, float] = {}  # request ids of the freshness window, by when they came
        self._queue: queue.Queue[bytes | None] = queue.Queue(maxsize=1000)
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="fleet-admin", daemon=True)
        self._thread.start()
        self.bus.subscribe(self.request_topic, self._take)
        self.bus.connect()
        if self.key is None:
            log.info("admin requests on %s are refused: this fleet has no fleet_admin_key", self.request_topic)

    def stop(self, timeout: float = 10.0) -> None:
        try:
            self._queue.put(None, timeout=timeout)
        except queue.Full:
            pass
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None
        try:
            self.bus.flush(min(timeout, 2.0))
        except BusError:
            pass
        self.bus.close()

    def _take(self, msg: Message) -> None:
        """(the bus's thread) Hand the request to the admin thread; a flood beyond the queue is dropped."""
        try:
            self._queue.put_nowait(msg.payload)
        except queue.Full:
            log.warning("admin requests: too many waiting, one dropped")

    def _run(self) -> None:
        while (raw := self._queue.get()) is not None:
            try:
                self.handle(raw)
            except Exception:  # one request must not end the admin thread
                log.exception("admin request failed")

    # -- one request ---------------------------------------------------------------------------------------

    def handle(self, raw: bytes) -> None:
        request: Any = None
        try:
            request = self._read(raw)
            if self.share is not None and min(self.share.live()) != self.share.me.node:
                self._note(request)  # another member answers
                return
            code, message = self._carry_out(request)
        except Refused as exc:
            code, message = exc.code, str(exc)
        rid = request.get("id") if isinstance(request, dict) and isinstance(request.get("id"), str) else None
        op = request.get("op") if isinstance(request, dict) and request.get("op") in OPS else None
        robot = request.get("robot") if isinstance(request, dict) and isinstance(request.get("robot"), str) else None
        self._answer(rid, op, robot if robot and ROBOT_ID.match(robot) else None, code, message)

    def _read(self, raw: bytes) -> dict[str, Any]:
        if len(raw) > MAX_REQUEST_BYTES:
            raise Refused("invalid", f"a request has at most {MAX_REQUEST_BYTES} bytes")
        try:
            request = json.loads(raw)
        except (ValueError, UnicodeDecodeError):
            raise Refused("invalid", "the request is not JSON") from None
        if not isinstance(request, dict):
            raise Refused("invalid", "the request must be a JSON object")
        return request

    def _carry_out(self, request: dict[str, Any]) -> tuple[str, str]:
        if self.key is None:
            raise Refused("refused", "this fleet has no admin: the edge node has no fleet_admin_key")
        self._authenticate(request)
        op, robot = request.get("op"), request.get("robot")
        if op not in OPS:
            raise Refused("invalid", f"op must be one of {', '.join(OPS)}")
        if not isinstance(robot, str) or not ROBOT_ID.match(robot) or robot == ALL_ROBOTS:
            raise Refused("invalid", "robot must be a robot id (1-128 letters, digits, '_', '.', '-')")
        if op == "remove":
            if self.share is not None:
                return self._remove_shared(robot)
            if not self.fleet.remove(robot, "was removed by an admin request"):
                raise Refused("not-served", f"robot {robot} is not served by this edge node")
            return "removed", f"robot {robot} is no longer served"
        namespace = request.get("namespace")
        if namespace is not None and not isinstance(namespace, str):
            raise Refused("invalid", "namespace must be a string")
        try:
            config = self.make_config(robot, namespace)
        except ConfigError as exc:
            raise Refused("invalid", str(exc)) from None
        if self.share is not None:
            return self._add_shared(robot, namespace, config, str(request["id"]))
        try:
            self.fleet.add(config, "admin")
        except FleetError as exc:
            code = "served-already" if exc.why == "served already" else "failed"
            raise Refused(code, str(exc)) from None
        return "added", f"robot {robot} is served (namespace {config.ros_namespace})"

    # -- a shared fleet ------------------------------------------------------------------------------------

    def _note(self, request: dict[str, Any]) -> None:
        """(not the answering member) Check the request as the answering one does, silently: its id is then known
        here too, should this process answer the next ones (the member that answered died)."""
        if self.key is not None:
            try:
                self._authenticate(request)
            except Refused:
                pass

    def _add_shared(self, robot: str, namespace: str | None, config: RuntimeConfig, rid: str) -> tuple[str, str]:
        share = self.share
        assert share is not None
        if robot in share.listed():
            raise Refused("served-already", f"robot {robot} is in the shared fleet {self.name} already")
        entry: dict[str, Any] = {"robot": robot, "request": rid, "time": now_rfc3339()}
        if namespace is not None:
            entry["namespace"] = namespace
        try:
            share.publish_entry(robot, entry)
        except BusError as exc:
            raise Refused("failed", f"robot {robot} could not be added: {exc}") from None
        owner = _wait(lambda: _served_by(share, robot), SHARED_WAIT)
        if owner is None:
            share.publish_entry(robot, None)
            raise Refused(
                "failed",
                f"robot {robot}: no process of the shared fleet served it within {SHARED_WAIT:g} s (their logs "
                "say why); it is not added",
            )
        return "added", f"robot {robot} is served by {owner} (namespace {config.ros_namespace})"

    def _remove_shared(self, robot: str) -> tuple[str, str]:
        share = self.share
        assert share is not None
        if robot not in share.admin_robots():
            if robot in share.listed():
                raise Refused(
                    "invalid",
                    f"robot {robot} was not added by an admin request: it is in the fleet file, or the ROS graph, of "
                    "a process of the shared fleet; remove it there",
                )
            raise Refused("not-served", f"robot {robot} is not in the shared fleet {self.name}")
        try:
            share.publish_entry(robot, None)
        except BusError as exc:
            raise Refused("failed", f"robot {robot} could not be removed: {exc}") from None
        if _wait(lambda: True if _served_by(share, robot) is None else None, SHARED_WAIT) is None:
            raise Refused("failed", f"robot {robot} left the shared fleet, but its owner has not yet stopped it")
        return "removed", f"robot {robot} is no longer served"

    def _authenticate(self, request: dict[str, Any]) -> None:
        """The signature, then freshness and novelty (the signature covers `id` and `time`)."""
        assert self.key is not None
        given = request.get("signature")
        wanted = sign(request, self.key)["signature"]
        if given is None:
            raise Refused("unauthorised", f"the request has no signature ({SIGNATURE})")
        if not isinstance(given, str):  # e.g. the whole signed request that sign() returns, put in `signature`
            raise Refused("unauthorised", f"signature must be a string: {SIGNATURE}")
        if not hmac.compare_digest(given.encode(), wanted.encode()):
            raise Refused("unauthorised", "the request is not signed with this fleet's admin key")
        rid, stamp = request.get("id"), request.get("time")
        if not isinstance(rid, str) or not rid or not isinstance(stamp, str):
            raise Refused("invalid", "a request needs an id and a time (RFC 3339)")
        when = parse_time(stamp)
        now = time.time()
        if when is None:
            raise Refused("invalid", f"time {stamp[:64]!r} is not an RFC 3339 date-time")
        if when < now - self.freshness_window or when > now + self.clock_skew:
            raise Refused("expired", "the request's time is outside the freshness window")
        self._seen = {r: t for r, t in self._seen.items() if t >= now - self.freshness_window - self.clock_skew}
        if rid in self._seen:
            raise Refused("replayed", f"request {rid[:64]!r} was taken already")
        self._seen[rid] = now

    def _answer(self, rid: str | None, op: str | None, robot: str | None, code: str, message: str) -> None:
        self.answered[code] = self.answered.get(code, 0) + 1
        ok = code in ("added", "removed")
        (log.info if ok else log.warning)("admin request %s: %s: %s", rid or "(no id)", code, message)
        payload: dict[str, Any] = {"ok": ok, "code": code, "message": message}
        if op is not None:
            payload["op"] = op
        if robot is not None:
            payload["robot"] = robot
        answer: dict[str, Any] = {"type": "fleet-answer", "id": new_id(), "time": now_rfc3339()}
        answer["source"] = f"td2adaptor/{ADMIN_LEVEL}/{self.name}"
        if rid is not None:
            answer["correlation"] = rid
        answer["payload"] = payload
        try:
            self.bus.publish(self.answer_topic, json.dumps(answer).encode("utf-8"))
        except BusError as exc:
            log.warning("could not publish the answer to admin request %s: %s", rid, exc)


def _served_by(share: Share, robot: str) -> str | None:
    """The live member that serves `robot` now, by its retained status (its words), or None."""
    status = share.status(robot)
    if status is None or status.state != "online" or status.owner is None or status.handover is not None:
        return None
    return status.owner.describe() if status.owner.node in share.live() else None


def _wait(look: Callable[[], Any], timeout: float) -> Any:
    """`look()` until it gives something other than None, for at most `timeout` seconds (it reads what the share's
    connection received: nothing to be woken by)."""
    deadline = time.monotonic() + timeout
    while (found := look()) is None and time.monotonic() < deadline:
        time.sleep(0.05)
    return found


def admin_bus(config: RuntimeConfig, model: Any, *, broker: Any = None) -> Bus:
    """The admin listener's own connection, as the robots' (`config`: the fleet's shared settings), with a
    clean session of its own client id (one per process: several processes of one fleet each answer)."""
    import os

    client_id = f"td2adaptor-fleet-{config.fleet or model.package_name}-{os.getpid()}"[:128]
    if config.bus == "local":
        from td2adaptor.runtime.bus.localbus import LocalBus

        return LocalBus(broker, client_id, clean_start=True)
    from td2adaptor.runtime.bus.mqttbus import MqttBus
    from td2adaptor.runtime.node.app import bus_security

    address, security = bus_security(config, model)
    return MqttBus.sessionless(
        address, security, "fleet", client_id=client_id, mqtt_version=config.mqtt_version, keepalive=config.keepalive
    )
