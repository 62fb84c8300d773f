"""The ROS 1 side of an edge node in ROS 1's own interpreter: `GeneratedPort`s behind a pipe.

rospy lives in the ROS 1 distribution's Python (Debian's /usr/bin/python3, /opt/ros/noetic's), which
usually has none of td2adaptor's dependencies; the edge node's engine and bus run where td2adaptor is
installed. `Ros1Bridge` starts `python -m td2adaptor.runtime.ros.bridge` under the ROS 1 interpreter with only
the td2adaptor package (through a symlink, never the rest of our environment) and the given paths on
PYTHONPATH; the child initialises one rospy node and serves every robot's `GeneratedPort` over stdin/stdout,
one JSON object per line, requests handled concurrently:

    parent → child   {"id": 0, "op": "init", "package": ..., "layout": ..., "robots": [[id, ns], ...], ...}
                     {"id": n, "robot": id, "op": "start" | "query" | ..., "args": [...]}
    child → parent   {"id": n, "ok": <result>}  or  {"id": n, "error": {"kind", "message", "response"}}
                     {"goal": tag, "event": "accepted" | "status" | "feedback" | "done", "value": ...}

A ROS action goal is followed by callbacks on both sides: the parent names each goal it starts with a tag
(`start_goal`'s first argument; `rejoin_goal`'s, for a goal it follows by its id), the child's `GoalListener`
writes what happens to the goal as lines carrying that tag, in order, and the parent's reader thread tells them
to the goal's listener; a cancel request is
answered when the server answers (`request_cancel`), not waited for. No parent thread waits for a goal.
`BridgePort` is the `RobotPort` of one robot on a bridge. A bridge that dies fails its calls as
`PortUnavailable`, ends the goals it followed as lost, and is restarted by the next call (at most every
`restart_period` seconds).
The child side imports only the standard library, `td2adaptor.runtime.ros.genport`, `.port` and `.words`.
"""

from __future__ import annotations

import importlib
import json
import logging
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import urllib.parse
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from td2adaptor.runtime.ros.genport import GeneratedPort, Layout
from td2adaptor.runtime.ros.port import (
    Answered,
    CancelDone,
    GoalEnd,
    GoalListener,
    NoValue,
    PortCallFailed,
    PortError,
    PortRejected,
    PortTimeout,
    PortUnavailable,
    RosSetupError,
    StalePackage,
    StartResult,
)
from td2adaptor.runtime.ros.words import DEFAULT_MASTER, import_failure, master_silent, setup_failure

ENV_PYTHON = "TD2ADAPTOR_ROS1_PYTHON"
log = logging.getLogger("td2adaptor.runtime")

_ERRORS: dict[str, type[PortError]] = {
    "PortUnavailable": PortUnavailable,
    "PortTimeout": PortTimeout,
    "PortCallFailed": PortCallFailed,
    "NoValue": NoValue,
    "PortRejected": PortRejected,
}
#: ROS 2 variables (and the ROS 2 wheels' loader state) a ROS 1 child must not inherit
_ROS2_ONLY = (
    "ROS_DOMAIN_ID",
    "ROS_AUTOMATIC_DISCOVERY_RANGE",
    "ROS_STATIC_PEERS",
    "ROS_LOCALHOST_ONLY",
    "ROS_VERSION",
    "ROS_DISTRO",
    "ROS_PYTHON_VERSION",
    "RMW_IMPLEMENTATION",
    "AMENT_PREFIX_PATH",
    "COLCON_PREFIX_PATH",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
    "FASTDDS_DEFAULT_PROFILES_FILE",
    "_ROS_WHEELS_BOOTSTRAP_COMPLETE",
    "PYTHONHOME",
    "PYTHONSTARTUP",
    "VIRTUAL_ENV",
)


def default_python(environ: Mapping[str, str] | None = None) -> str | None:
    """The ROS 1 interpreter: $TD2ADAPTOR_ROS1_PYTHON, else /usr/bin/python3 when it exists."""
    environ = os.environ if environ is None else environ
    if environ.get(ENV_PYTHON):
        return environ[ENV_PYTHON]
    return "/usr/bin/python3" if os.access("/usr/bin/python3", os.X_OK) else None


def _inside(path: str, root: str) -> bool:
    try:
        return os.path.commonpath([os.path.abspath(path), root]) == root
    except ValueError:
        return False


def master_unreachable(uri: str, timeout: float = 2.0) -> str | None:
    """Why a TCP connection to the ROS 1 master at `uri` fails, in words (words.py `master_silent`; None when
    it connects)."""
    parsed = urllib.parse.urlsplit(uri)
    try:
        with socket.create_connection((parsed.hostname or "localhost", parsed.port or 11311), timeout=timeout):
            return None
    except OSError as exc:
        return master_silent(uri, exc)
    except ValueError as exc:  # a port that is no number
        return master_silent(uri, str(exc))


def child_environment(environ: Mapping[str, str], pythonpath: Sequence[str], master_uri: str | None) -> dict[str, str]:
    """The ROS 1 child's environment: ours without ROS 2 and this interpreter's paths, plus `pythonpath`."""
    prefix = os.path.abspath(sys.prefix)
    env = {k: v for k, v in environ.items() if k not in _ROS2_ONLY}
    inherited = [p for p in environ.get("PYTHONPATH", "").split(os.pathsep) if p and not _inside(p, prefix)]
    env["PYTHONPATH"] = os.pathsep.join([*pythonpath, *inherited])
    libs = [p for p in environ.get("LD_LIBRARY_PATH", "").split(os.pathsep) if p and not _inside(p, prefix)]
    if "_ROS_WHEELS_BOOTSTRAP_COMPLETE" in environ:  # the ROS 2 wheels set it for this process only
        libs = [p for p in libs if "ros_" not in os.path.basename(p)]
    if libs:
        env["LD_LIBRARY_PATH"] = os.pathsep.join(libs)
    else:
        env.pop("LD_LIBRARY_PATH", None)
    if master_uri:
        env["ROS_MASTER_URI"] = master_uri
    env["PYTHONUNBUFFERED"] = "1"
    return env


# ---------------------------------------------------------------------------------------------------------
# parent side


class Ros1Bridge:
    """A ROS 1 interpreter serving the `GeneratedPort`s of `robots` ((robot id, namespace) pairs)."""

    def __init__(
        self,
        layout: Layout,
        package: str,
        robots: Sequence[tuple[str, str]],
        *,
        python: str,
        pythonpath: Sequence[Path] = (),
        master_uri: str | None = None,
        node_name: str = "td2adaptor_edge",
        timeout: float = 10.0,
        wait_timeout: float | None = None,
        feedback_grace: Mapping[str, float | None] | None = None,
        environ: Mapping[str, str] | None = None,
        start_timeout: float = 30.0,
        restart_period: float = 5.0,
    ) -> None:
        self.layout = layout
        self.package = package
        self.robots = list(robots)
        self.python = python
        self.pythonpath = [str(Path(p).resolve()) for p in pythonpath]
        self.master_uri = master_uri
        self.node_name = node_name
        self.timeout = timeout
        self.wait_timeout = timeout if wait_timeout is None else wait_timeout
        self.feedback_grace = dict(feedback_grace or {})  # per robot id; absent or None: the ROS 1 default
        self.environ = dict(os.environ if environ is None else environ)
        self.start_timeout = start_timeout
        self.restart_period = restart_period
        self.starts = 0
        self._lock = threading.Lock()
        self._proc: subprocess.Popen[bytes] | None = None
        self._pending: dict[int, Callable[[dict[str, Any]], None]] = {}  # by request id: who takes the reply
        self._listeners: dict[str, GoalListener] = {}  # by tag: the goals followed through the child
        self._next_id = 1
        self._stderr: deque[str] = deque(maxlen=20)
        self._shim: str | None = None
        self._last_start = -1e9
        self._closed = False
        self._readers: list[threading.Thread] = []
        self._serving: subprocess.Popen[bytes] | None = None  # the child that started serving last

    # -- life cycle ----------------------------------------------------------------------------------------

    def _shim_dir(self) -> str:
        """A directory holding only a link to the td2adaptor package (our site-packages would shadow ROS 1's)."""
        if self._shim is None:
            import td2adaptor

            self._shim = tempfile.mkdtemp(prefix="td2adaptor-bridge-")
            os.symlink(Path(td2adaptor.__file__).resolve().parent, os.path.join(self._shim, "td2adaptor"))
        return self._shim

    def start(self) -> None:
        """Start the child and wait until its node and ports are up; raises `PortUnavailable` on failure."""
        with self._lock:
            if self._closed:
                raise PortUnavailable("the ROS 1 bridge is closed")
            if self._proc is not None and self._proc.poll() is None:
                return
            self._last_start = time.monotonic()
            self.starts += 1
            if self._proc is not None:  # a dead predecessor: its readers close its output streams
                self._close_input(self._proc)
            env = child_environment(self.environ, [self._shim_dir(), *self.pythonpath], self.master_uri)
            try:
                proc = subprocess.Popen(
                    [self.python, "-m", "td2adaptor.runtime.ros.bridge"],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    env=env,
                )
            except OSError as exc:
                raise RosSetupError(
                    f"cannot start the ROS 1 interpreter {self.python}: {exc.strerror or exc}"
                ) from None
            self._proc = proc
            self._stderr.clear()
            self._readers = [
                threading.Thread(target=self._read, args=(proc,), name="ros1-bridge-reader", daemon=True),
                threading.Thread(target=self._relay, args=(proc,), name="ros1-bridge-stderr", daemon=True),
            ]
            # the child's first line says what to serve: written before the lock lets a call see the child (the
            # property reads of a fleet's robots, in parallel, wrote theirs first, and the child took one for it)
            init = self._reply_box()
            try:
                rid: int | PortError = self._send_locked(None, "init", [self.init_request()], init[0])
            except PortError as exc:  # it died at once
                rid = exc
        for reader in self._readers:
            reader.start()
        try:
            if isinstance(rid, PortError):
                raise rid
            self._await(rid, init, "init", self.start_timeout)
            self._serving = proc
        except StalePackage:
            self._kill()
            raise
        except PortError as exc:
            self._kill()
            master = self.master_uri or self.environ.get("ROS_MASTER_URI") or DEFAULT_MASTER
            unreachable = master_unreachable(master) if isinstance(exc, PortTimeout) else None
            if unreachable is not None:  # rospy waits for ever for a master that is not up: say so, not "init"
                raise RosSetupError(f"the ROS 1 bridge under {self.python} did not start: {unreachable}") from None
            raise RosSetupError(f"the ROS 1 bridge under {self.python} did not start: {exc}") from None
        except BaseException:  # interrupted (Ctrl-C while rospy waits for a master that is not up): no orphan
            self._kill(at_once=True)
            raise

    def init_request(self) -> dict[str, Any]:
        """What the child is told first: the package, the robots and the settings of their ports."""
        return {
            "package": self.package,
            "layout": self.layout.to_json(),
            "robots": [list(r) for r in self.robots],
            "node": self.node_name,
            "timeout": self.timeout,
            "wait_timeout": self.wait_timeout,
            "feedback_grace": self.feedback_grace,
        }

    def close(self) -> None:
        """Stop the child (it leaves the ROS graph) and remove the package link."""
        with self._lock:
            self._closed = True
            proc = self._proc
        if proc is not None and proc.poll() is None:
            try:
                assert proc.stdin is not None
                proc.stdin.close()  # EOF: the child shuts its node down and exits
                proc.wait(5)
            except (OSError, subprocess.TimeoutExpired):
                pass
        self._kill()
        for reader in self._readers:
            reader.join(5)
        if self._shim is not None:
            shutil.rmtree(self._shim, ignore_errors=True)
            self._shim = None

    def _kill(self, at_once: bool = False) -> None:
        """End the child: SIGTERM, then SIGKILL after 5 s (`at_once`: SIGKILL, for a child that never served)."""
        proc = self._proc
        if proc is None:
            return
        if proc.poll() is None and at_once:
            proc.kill()
            proc.wait(5)
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        self._close_input(proc)

    @staticmethod
    def _close_input(proc: subprocess.Popen[bytes]) -> None:
        if proc.stdin is not None:
            try:
                proc.stdin.close()
            except OSError:
                pass

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    # -- traffic -------------------------------------------------------------------------------------------

    def _relay(self, proc: subprocess.Popen[bytes]) -> None:
        assert proc.stderr is not None
        with proc.stderr:
            for raw in proc.stderr:
                line = raw.decode("utf-8", "replace").rstrip()
                if line:
                    self._stderr.append(line)
                    print(f"[ros1 bridge] {line}", file=sys.stderr, flush=True)

    def _read(self, proc: subprocess.Popen[bytes]) -> None:
        assert proc.stdout is not None
        with proc.stdout:
            for raw in proc.stdout:
                try:
                    reply = json.loads(raw)
                    if "goal" in reply:
                        self._goal_event(reply)
                        continue
                    deliver = self._pending.pop(int(reply["id"]), None)
                except (ValueError, KeyError, TypeError):
                    continue
                if deliver is not None:
                    deliver(reply)
        code = proc.wait()
        time.sleep(0.05)  # let the stderr relay catch the last words
        why = f"the ROS 1 bridge exited with code {code}" + (f": {self._stderr[-1]}" if self._stderr else "")
        with self._lock:
            if self._proc is proc:
                pending, self._pending = self._pending, {}
                listeners, self._listeners = self._listeners, {}
            else:
                pending, listeners = {}, {}
            unexpected = self._serving is proc and not self._closed
        if unexpected:  # else the operator learns of it only from the calls that fail meanwhile
            log.warning("%s (process %d); the next call starts it again", why, proc.pid)
        for deliver in pending.values():
            deliver({"error": {"kind": "PortUnavailable", "message": why}})
        for listener in listeners.values():
            listener.on_done(GoalEnd("lost", message=why, error=PortUnavailable(why)))

    def _goal_event(self, line: Mapping[str, Any]) -> None:
        """A line about a goal followed through the child (the reader's thread): to its listener."""
        tag, event, value = str(line["goal"]), line.get("event"), line.get("value")
        if event == "done":
            with self._lock:
                listener = self._listeners.pop(tag, None)
        else:
            listener = self._listeners.get(tag)
        if listener is None:  # forgotten meanwhile
            return
        if event == "accepted":
            listener.on_accepted(str(value))
        elif event == "status":
            listener.on_status(str(value))
        elif event == "feedback":
            listener.on_feedback(value)
        elif event == "done":
            listener.on_done(GoalEnd.from_json(value if isinstance(value, Mapping) else {}))

    def _send(
        self, robot: str | None, op: str, args: list[Any], deliver: Callable[[dict[str, Any]], None] | None
    ) -> int:
        """Write one request; `deliver` is given its reply (in the reader's thread), None: nobody waits for one."""
        with self._lock:
            return self._send_locked(robot, op, args, deliver)

    def _send_locked(
        self, robot: str | None, op: str, args: list[Any], deliver: Callable[[dict[str, Any]], None] | None
    ) -> int:
        """`_send` with the lock held."""
        proc = self._proc
        if proc is None or proc.poll() is not None or proc.stdin is None:
            raise PortUnavailable("the ROS 1 bridge is not running")
        rid = 0 if op == "init" else self._next_id
        self._next_id += 1
        if deliver is not None:
            self._pending[rid] = deliver
        line = json.dumps({"id": rid, "robot": robot, "op": op, "args": args}) + "\n"
        try:
            proc.stdin.write(line.encode("utf-8"))
            proc.stdin.flush()
        except (OSError, ValueError):
            self._pending.pop(rid, None)
            raise PortUnavailable("the ROS 1 bridge is not running (its input is closed)") from None
        return rid

    @staticmethod
    def _reply_box() -> tuple[Callable[[dict[str, Any]], None], threading.Event, list[dict[str, Any]]]:
        """(deliver, set once the reply came, the reply): what a request waits on."""
        event = threading.Event()
        box: list[dict[str, Any]] = []

        def deliver(reply: dict[str, Any]) -> None:
            box.append(reply)
            event.set()

        return deliver, event, box

    def _await(
        self,
        rid: int,
        waiting: tuple[Callable[[dict[str, Any]], None], threading.Event, list[dict[str, Any]]],
        op: str,
        timeout: float,
    ) -> Any:
        _deliver, event, box = waiting
        if not event.wait(timeout):
            self._pending.pop(rid, None)
            raise PortTimeout(f"the ROS 1 bridge did not answer {op} within {timeout:g} s")
        return _outcome(box[0], self.package)

    def _request(self, robot: str | None, op: str, args: list[Any], timeout: float) -> Any:
        waiting = self._reply_box()
        rid = self._send(robot, op, args, waiting[0])
        return self._await(rid, waiting, op, timeout)

    def _ensure_started(self) -> None:
        """Restart a dead child first, if it is time to."""
        proc = self._proc
        if (proc is None or proc.poll() is not None) and not self._closed:
            if time.monotonic() - self._last_start >= self.restart_period:
                try:
                    self.start()
                except Exception as exc:  # noqa: BLE001 - reported as the call's failure
                    raise PortUnavailable(f"restarting the ROS 1 bridge failed: {exc}") from None

    def call(self, robot: str, op: str, args: list[Any], timeout: float) -> Any:
        """Run `op` on `robot`'s port in the child (restarting a dead child first, if it is time to)."""
        self._ensure_started()
        # the child bounds each call by wait_timeout + timeout; the margin covers the pipe and the scheduler
        return self._request(robot, op, args, timeout + self.wait_timeout + 5.0)

    def start_goal(
        self, robot: str, args: list[Any], listener: GoalListener, timeout: float, op: str = "start_goal"
    ) -> str:
        """Start a goal in the child (`op` "rejoin_goal": follow one the server has, by its id), followed by
        `listener` (told by the reader's thread); its id."""
        self._ensure_started()
        with self._lock:
            tag = f"g{self._next_id}"
            self._next_id += 1
            self._listeners[tag] = listener  # before the request: the child may tell before it answers
        try:
            return str(self._request(robot, op, [tag, *args], timeout + self.wait_timeout + 5.0))
        except BaseException:
            with self._lock:
                self._listeners.pop(tag, None)
            raise

    def forget(self, listener: GoalListener) -> None:
        """`listener` is told nothing more."""
        with self._lock:
            for tag, known in list(self._listeners.items()):
                if known is listener:
                    del self._listeners[tag]

    def ask(self, robot: str, op: str, args: list[Any], answer: Callable[[Any, PortError | None], None]) -> None:
        """Run `op` in the child without waiting: `answer(result, error)` is told its reply (the reader's thread;
        here when the request cannot be sent)."""

        def deliver(reply: dict[str, Any]) -> None:
            try:
                value = _outcome(reply, self.package)
            except PortError as exc:
                answer(None, exc)
                return
            answer(value, None)

        try:
            self._send(robot, op, args, deliver)
        except PortError as exc:
            answer(None, exc)

    def try_ask(self, robot: str, op: str, args: list[Any], answer: Callable[[Any, PortError | None], None]) -> bool:
        """`ask` when the child runs (a dead one is restarted by `call` only: that waits); False, nothing sent,
        otherwise. The child bounds each call by wait_timeout + timeout, and a child that dies answers every
        request it had with PortUnavailable."""
        proc = self._proc
        if proc is None or proc.poll() is not None or self._closed:
            return False
        self.ask(robot, op, args, answer)
        return True

    def port(self, robot: str) -> BridgePort:
        return BridgePort(self, robot)


class BridgePort:
    """The `RobotPort` of one robot served by a `Ros1Bridge`."""

    distro = "ros1"  # its messages have ROS 1 layouts (times in secs/nsecs): what `serve` follows by default

    def __init__(self, bridge: Ros1Bridge, robot: str) -> None:
        self.bridge = bridge
        self.robot = robot
        self._listeners: dict[tuple[str, str, str], GoalListener] = {}

    def start(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> StartResult:
        return _start_of(self.bridge.call(self.robot, "start", [component, action, dict(payload), timeout], timeout))

    def query(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        return self.bridge.call(self.robot, "query", [component, action, mission_id, timeout], timeout)  # type: ignore[no-any-return]

    def cancel(self, component: str, action: str, mission_id: int, timeout: float) -> Mapping[str, Any]:
        return self.bridge.call(self.robot, "cancel", [component, action, mission_id, timeout], timeout)  # type: ignore[no-any-return]

    def call(self, component: str, action: str, payload: Mapping[str, Any], timeout: float) -> Mapping[str, Any]:
        return self.bridge.call(self.robot, "call", [component, action, dict(payload), timeout], timeout)  # type: ignore[no-any-return]

    def read_property(self, component: str, name: str, timeout: float) -> Any:
        return self.bridge.call(self.robot, "read_property", [component, name, timeout], timeout)

    # calls without a waiting thread (`QuickCall`): the request is written from the caller's thread and the reply
    # told by the bridge's reader, which would otherwise wake a thread waiting for it

    def try_start(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, on_done: Answered
    ) -> bool:
        def started(out: Any, error: PortError | None) -> None:
            if error is not None:
                on_done(None, error)
                return
            try:
                result = _start_of(out)
            except (AttributeError, KeyError, TypeError, ValueError) as exc:
                on_done(None, PortCallFailed(f"the ROS 1 bridge's answer to {action} is not a start's: {exc}"))
                return
            on_done(result, None)

        return self.bridge.try_ask(self.robot, "start", [component, action, dict(payload), timeout], started)

    def try_query(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        return self.bridge.try_ask(self.robot, "query", [component, action, mission_id, timeout], on_done)

    def try_cancel(self, component: str, action: str, mission_id: int, timeout: float, on_done: Answered) -> bool:
        return self.bridge.try_ask(self.robot, "cancel", [component, action, mission_id, timeout], on_done)

    def try_call(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, on_done: Answered
    ) -> bool:
        return self.bridge.try_ask(self.robot, "call", [component, action, dict(payload), timeout], on_done)

    def write_property(self, component: str, name: str, value: Any) -> None:
        self.bridge.call(self.robot, "write_property", [component, name, value], self.bridge.timeout)

    # ROS actions: the child follows the goal and tells the parent what happens, by lines read here

    def start_goal(
        self, component: str, action: str, payload: Mapping[str, Any], timeout: float, listener: GoalListener
    ) -> str:
        goal = self.bridge.start_goal(self.robot, [component, action, dict(payload), timeout], listener, timeout)
        self._listeners[(component, action, goal)] = listener
        return goal

    def rejoin_goal(self, component: str, action: str, goal: str, timeout: float, listener: GoalListener) -> None:
        """Follow in the child a goal the server took from another client, by its id (`GoalRejoin`)."""
        args = [component, action, goal, timeout]
        self.bridge.start_goal(self.robot, args, listener, timeout, op="rejoin_goal")
        self._listeners[(component, action, goal)] = listener

    def request_cancel(self, component: str, action: str, goal: str, timeout: float, on_done: CancelDone) -> None:
        self.bridge.ask(
            self.robot,
            "request_cancel",
            [component, action, goal, timeout],
            lambda value, error: on_done(bool(value), error),
        )

    def forget_goal(self, component: str, action: str, goal: str) -> None:
        listener = self._listeners.pop((component, action, goal), None)
        if listener is not None:
            self.bridge.forget(listener)
        try:
            self.bridge.ask(self.robot, "forget_goal", [component, action, goal], lambda value, error: None)
        except Exception:  # noqa: BLE001, S110 - a dead child has forgotten it already
            pass


def _start_of(out: Any) -> StartResult:
    """A start's answer as the child sends it (`mission_id`, `response`)."""
    mission = out.get("mission_id")
    return StartResult(out["response"], int(mission) if mission is not None else None)


def _outcome(reply: Mapping[str, Any], package: str) -> Any:
    """A reply's result, or its error raised as the port error it names."""
    if "error" in reply:
        error = reply["error"]
        if error.get("kind") == "StalePackage":  # the package is not of this TD: the user's to regenerate
            raise StalePackage(str(error.get("message", "")), package, "ros1")
        cls = _ERRORS.get(str(error.get("kind")), PortCallFailed)
        response = error.get("response")
        raise cls(str(error.get("message", "")), response=response if isinstance(response, Mapping) else None)
    return reply.get("ok")


class _Relay:
    """The child's listener of one goal: each event a line for the parent, carrying the parent's tag."""

    def __init__(self, tag: str, write: Callable[[dict[str, Any]], None]) -> None:
        self.tag = tag
        self.write = write

    def on_accepted(self, goal: str) -> None:
        self.write({"goal": self.tag, "event": "accepted", "value": goal})

    def on_status(self, status: str) -> None:
        self.write({"goal": self.tag, "event": "status", "value": status})

    def on_feedback(self, message: Any) -> None:
        self.write({"goal": self.tag, "event": "feedback", "value": message})

    def on_done(self, end: GoalEnd) -> None:
        self.write({"goal": self.tag, "event": "done", "value": end.to_json()})


# ---------------------------------------------------------------------------------------------------------
# child side


#: the child's threads that read requests and run them (one reads while the others run theirs)
BRIDGE_THREADS = 33


def _serve(requests: IO[str], replies: IO[str]) -> int:
    """The child's loop: init, then requests until EOF or a close request."""
    write_lock = threading.Lock()

    def reply(message: dict[str, Any]) -> None:
        text = json.dumps(message, default=str)
        with write_lock:
            replies.write(text + "\n")
            replies.flush()

    def error(rid: Any, exc: BaseException) -> None:
        kind = type(exc).__name__ if isinstance(exc, PortError) else "PortCallFailed"
        response = exc.response if isinstance(exc, PortError) else None
        # the message as the error says it, maybe empty: the parent's words then say what failed (words.py)
        reply({"id": rid, "error": {"kind": kind, "message": str(exc), "response": response}})

    first = requests.readline()
    if not first:
        return 0
    request = json.loads(first)
    ports: dict[str, GeneratedPort] = {}
    try:
        init = request["args"][0]
        rospy: Any = importlib.import_module("rospy")
        rospy.init_node(init["node"], anonymous=True, disable_signals=True)
        layout = Layout.from_json(init["layout"])
        try:
            package = importlib.import_module(init["package"])
        except ImportError as exc:
            raise PortCallFailed(import_failure(init["package"], exc)) from None
        for robot, namespace in init["robots"]:
            try:
                ports[robot] = GeneratedPort(
                    layout,
                    package,
                    namespace,
                    distro="ros1",
                    timeout=float(init["timeout"]),
                    wait_timeout=float(init["wait_timeout"]),
                    feedback_grace=(init.get("feedback_grace") or {}).get(robot),
                )
            except ValueError as exc:  # InvalidRobotName of the generated package
                raise PortCallFailed(f"robot {robot}: {setup_failure(exc)}") from None
    except StalePackage as exc:
        reply({"id": request.get("id", 0), "error": {"kind": "StalePackage", "message": str(exc), "response": None}})
        return 1
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which explains it (the details: stderr)
        if not isinstance(exc, PortError):
            traceback.print_exc()  # relayed to the parent's stderr: the class and where, for a developer
        error(request.get("id", 0), exc if isinstance(exc, PortError) else PortCallFailed(setup_failure(exc)))
        return 1
    reply({"id": request.get("id", 0), "ok": {"pid": os.getpid(), "python": sys.version.split()[0]}})

    def run(message: dict[str, Any]) -> None:
        rid = message.get("id")
        try:
            port = ports[message["robot"]]
            op, args = message["op"], message["args"]
            if op == "start":
                started = port.start(*args)
                reply({"id": rid, "ok": {"response": started.response, "mission_id": started.mission_id}})
            elif op == "start_goal":
                tag, component, action, payload, timeout = args
                goal = port.start_goal(component, action, payload, timeout, _Relay(str(tag), reply))
                reply({"id": rid, "ok": goal})
            elif op == "rejoin_goal":
                tag, component, action, goal, timeout = args
                port.rejoin_goal(component, action, goal, timeout, _Relay(str(tag), reply))
                reply({"id": rid, "ok": goal})
            elif op == "request_cancel":

                def answered(canceling: bool, failure: PortError | None) -> None:
                    if failure is not None:
                        error(rid, failure)
                    else:
                        reply({"id": rid, "ok": canceling})

                component, action, goal, timeout = args
                port.request_cancel(component, action, goal, timeout, answered)
            elif op in ("query", "cancel", "call", "read_property", "write_property"):
                reply({"id": rid, "ok": getattr(port, op)(*args)})
            elif op == "forget_goal":
                port.forget_goal(*args)
                reply({"id": rid, "ok": None})
            else:
                raise PortCallFailed(f"unknown bridge operation {op!r}")
        except Exception as exc:  # noqa: BLE001 - every failure is an answer
            error(rid, exc)

    finished = threading.Event()
    failed: list[BaseException] = []
    reading = threading.Lock()  # held by the one thread that reads the next request

    def serve() -> None:
        """Read a request, then run it on this very thread while another one reads the next: a request
        handed to a pool thread waited for that thread to wake (and take the interpreter lock), about a third
        of the child's time per query; here the next reader is woken (by the lock's release) beside the call,
        not before it. Up to BRIDGE_THREADS - 1 requests run at once, as the pool's workers did."""
        while not finished.is_set():
            with reading:
                if finished.is_set():
                    return
                try:
                    line = requests.readline()
                    message = json.loads(line) if line.strip() else None
                    closing = not line or (message is not None and message.get("op") == "close")
                except BaseException as exc:  # noqa: BLE001 - the child's loop ends, as the parent's stream did
                    failed.append(exc)
                    finished.set()
                    return
                if closing:
                    finished.set()
                    return
            if message is not None:
                run(message)

    for i in range(BRIDGE_THREADS):
        threading.Thread(target=serve, name=f"bridge_{i}", daemon=True).start()
    try:
        finished.wait()
        if failed:
            raise failed[0]
    finally:
        for port in ports.values():
            try:
                port.close()
            except Exception:  # noqa: BLE001 - leaving anyway
                pass
        importlib.import_module("rospy").signal_shutdown("td2adaptor bridge closed")
    return 0


#: seconds the child lives on once its parent is gone (a clean shutdown, started by its input closing, ends first)
ORPHAN_GRACE = 5.0


def _leave_with(parent: int) -> None:
    """(a daemon thread of the child) End the child once its parent is gone. The parent's death closes the
    child's input, which ends it, but only once it reads it: rospy's wait for a master that is not up reads
    nothing (and the child ignores SIGINT/SIGTERM), so a `run` stopped or killed meanwhile left it running."""
    while os.getppid() == parent:
        time.sleep(1.0)
    time.sleep(ORPHAN_GRACE)
    os._exit(1)


def main() -> int:
    """`python -m td2adaptor.runtime.ros.bridge`: requests on stdin, replies on the original stdout."""
    threading.Thread(target=_leave_with, args=(os.getppid(),), name="bridge-orphan", daemon=True).start()
    # The parent ends the bridge by closing its input (its death closes it too). A SIGINT/SIGTERM sent to the
    # whole process group (Ctrl-C, a launch system stopping the node) must not end it first: the parent would
    # log the property reads of its last moments as failures of a clean stop.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    replies = os.fdopen(os.dup(1), "w", encoding="utf-8")
    os.dup2(2, 1)  # anything else that prints (rospy, user code) goes to stderr, not into the protocol
    sys.stdout = sys.stderr
    return _serve(sys.stdin, replies)


if __name__ == "__main__":
    sys.exit(main())
