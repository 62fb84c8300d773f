"""`td2adaptor demo warehouse`: the BRAIN-IoT warehouse use case on ROS 2 Jazzy with simulated robots.

What runs (everything on one private-by-default, localhost-only ROS graph):

* the simulated robots, one process serving three: RB-1s (`examples/robotnik_rb1/sim/ros2.py`, rb1_base_a/b/c:
  procedures on services) or, with `--robot-kind nav_base`, Nav2-style bases (`examples/nav_base/sim/ros2.py`,
  nav_base_a/b/c: ROS actions);
* a simulated door controller (`examples.warehouse.doorsim`) for door1;
* the edge nodes: the robots' (from their example's TD) and the door's (from `door.td.json`), through adaptors
  generated on the fly with the rclpy backend — in this process on the in-process bus (`--bus local`), or
  each robot's and the door's in its own `td2adaptor run` process on an MQTT broker (`--bus mqtt://...`);
* the behaviour service (`behaviour.py`), which talks only events over the bus and moves three carts from
  their picking points through the door into storage zones A, B and C.

It builds the robots' interfaces with CMake on first use (cached in `.cache/ros2-interfaces` of the source
checkout, shared with the tests) and needs the source checkout for the example robot and its simulation.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from examples.warehouse.behaviour import BehaviourService, Cart, CartResult, TaskTable
from td2adaptor.model import Model

ROBOT_IDS = ("rb1_base_a", "rb1_base_b", "rb1_base_c")
DOOR = "door1"
DOOR_FRONT = (4.5, 0.0)  # the door itself is at (5, 0): marker 1 of the simulation
CARTS = (
    Cart("cart2", 2, (0.0, 3.0), "A", (8.0, -2.0)),
    Cart("cart3", 3, (1.5, 3.0), "B", (8.0, 0.0)),
    Cart("cart4", 4, (3.0, 3.0), "C", (8.0, 2.0)),
)
HERE = Path(__file__).resolve().parent
DOOR_TD = HERE / "door.td.json"


@dataclass(frozen=True)
class RobotKind:
    """An example robot the demo can run with: its folder under examples/, robot ids and simulation."""

    name: str
    label: str
    example: str
    robot_ids: tuple[str, ...]
    sim_module: str

    def sim_args(self, duration: float) -> list[str]:
        """The simulation's pace: RB-1 procedures take `duration`; a nav_base drives 3 m and docks in that time."""
        if self.name == "nav_base":
            return ["--speed", f"{3.0 / duration:g}", "--dock-time", f"{duration:g}"]
        return ["--duration", str(duration)]


KINDS = {
    "rb1": RobotKind("rb1", "RB-1", "robotnik_rb1", ROBOT_IDS, "examples.robotnik_rb1.sim.ros2"),
    "nav_base": RobotKind(
        "nav_base", "nav_base", "nav_base", ("nav_base_a", "nav_base_b", "nav_base_c"), "examples.nav_base.sim.ros2"
    ),
}


class DemoError(Exception):
    """The demo cannot run here (missing ROS 2, checkout, broker, ...); the message says what to do."""


@dataclass(frozen=True)
class WarehouseOptions:
    bus: str = "local"
    robots: int = 3
    duration: float = 1.0  # seconds a simulated procedure runs
    timeout: float = 120.0
    cache_dir: Path | None = None
    allow_insecure: bool = False
    verbose: bool = False
    robot_kind: str = "rb1"  # a key of KINDS


# ---------------------------------------------------------------------------------------------------------
# set-up


def checkout(kind: RobotKind = KINDS["rb1"]) -> Path:
    """The source checkout's example of the robot kind (TD, interfaces, simulation)."""
    example = HERE.parents[1] / "examples" / kind.example
    needed = [example / "td.json", example / "interfaces", example / "sim" / "ros2.py"]
    if not all(p.exists() for p in needed):
        raise DemoError(
            f"the warehouse demo runs from a source checkout of td2adaptor: {example} (the {kind.label} example "
            "and its simulation) was not found"
        )
    return example


def ros_environment() -> None:
    """ROS 2 defaults for a demo on one machine (kept when already set): localhost discovery, Fast DDS."""
    if importlib_find("rclpy") is None:
        raise DemoError("ROS 2 Jazzy (rclpy) is not installed: bash .ci/setup-ros2.sh, or pip install -e '.[ros2]'")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    profile = str(HERE / "fastdds.xml")  # faster discovery of new participants on localhost
    os.environ.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", profile)
    os.environ.setdefault("FASTDDS_DEFAULT_PROFILES_FILE", os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"])
    if "ROS_LOCALHOST_ONLY" in os.environ and "ROS_AUTOMATIC_DISCOVERY_RANGE" in os.environ:
        os.environ.pop("ROS_LOCALHOST_ONLY")  # deprecated in Jazzy; would only log warnings


def importlib_find(name: str) -> Any:
    import importlib.util

    return importlib.util.find_spec(name)


def compile_td(td: Path, interfaces: Sequence[Path]) -> Model:
    import td2adaptor

    result = td2adaptor.compile(td, interfaces=list(interfaces))
    if result.model is None:
        problems = "; ".join(d.message for d in result.diagnostics if d.severity.value == "error")
        raise DemoError(f"{td} does not compile: {problems}")
    return result.model


def generate_rclpy(model: Model, out: Path) -> Path:
    """The model's rclpy adaptor written under `out`; the package's source directory (to import from)."""
    from td2adaptor.backends.registry import load as load_backend
    from td2adaptor.diagnostics import Diagnostics, Severity
    from td2adaptor.generation.backend import GenOptions

    diags = Diagnostics()
    tree = load_backend("rclpy").generate(model, GenOptions(), diags)
    errors = [d.message for d in diags if d.severity is Severity.ERROR]
    if errors:
        raise DemoError(f"generating the adaptor of {model.thing.title} failed: {errors[0]}")
    for rel, data in tree:
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    return out / model.package_name


def build_interfaces(example: Path, cache: Path | None, say: Callable[[str], None], label: str = "RB-1") -> Path:
    from td2adaptor.support import ros2build

    root = HERE.parents[1] / ".cache"
    cache = cache or root / "ros2-interfaces"
    src = example / "interfaces"
    if not (cache.resolve() / ros2build.definitions_hash(src.resolve()) / "DONE").is_file():
        say(f"building the {label} interfaces with CMake (once; cached in {cache}) ...")
    try:
        return ros2build.build_interfaces(src, cache, colcon_home=root / "colcon-home")
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        raise DemoError(f"building the {label} interfaces failed: {str(exc)[:2000]}") from None


class Child:
    """A child process printing JSON lines on stdout (the simulations); stderr goes to a log file."""

    def __init__(self, name: str, args: list[str], cwd: Path, log: Path) -> None:
        self.name = name
        self.log = log
        self._log_file = log.open("wb")
        self.proc = subprocess.Popen(args, cwd=cwd, stdout=subprocess.PIPE, stderr=self._log_file, text=True)
        self.events: queue.Queue[dict[str, Any]] = queue.Queue()
        threading.Thread(target=self._read, name=f"{name}-reader", daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            try:
                self.events.put(json.loads(line))
            except ValueError:
                continue

    def wait_for(self, event: str, timeout: float) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                got = self.events.get(timeout=0.1)
            except queue.Empty:
                if self.proc.poll() is not None:
                    break
                continue
            if got.get("event") == event:
                return got
        raise DemoError(f"{self.name} did not start ({self.why()})")

    def why(self) -> str:
        code = self.proc.poll()
        tail = tail_of(self.log)
        return (f"exit code {code}" if code is not None else "still running") + (f": {tail}" if tail else "")

    def stop(self) -> None:
        stop_process(self.proc)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self._log_file.close()


def stop_process(proc: subprocess.Popen[Any]) -> None:
    """SIGTERM (a clean stop: edge nodes publish offline), SIGKILL after 10 s."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


def tail_of(path: Path, lines: int = 3) -> str:
    try:
        text = path.read_text(encoding="utf-8", errors="replace").strip().splitlines()
    except OSError:
        return ""
    return " | ".join(text[-lines:])


# ---------------------------------------------------------------------------------------------------------
# the run


@dataclass
class Setup:
    example: Path
    work: Path
    prefix: Path
    robot_model: Model
    door_model: Model
    robot_src: Path
    door_src: Path


def robot_kind(options: WarehouseOptions) -> RobotKind:
    kind = KINDS.get(options.robot_kind)
    if kind is None:
        raise DemoError(f"--robot-kind {options.robot_kind!r}: one of {', '.join(KINDS)}")
    return kind


def prepare(options: WarehouseOptions, work: Path, say: Callable[[str], None]) -> Setup:
    kind = robot_kind(options)
    example = checkout(kind)
    ros_environment()
    prefix = build_interfaces(example, options.cache_dir, say, kind.label)
    robot_model = compile_td(example / "td.json", [example / "interfaces"])
    door_model = compile_td(DOOR_TD, [])
    robot_src = generate_rclpy(robot_model, work / "src")
    door_src = generate_rclpy(door_model, work / "src")
    return Setup(example, work, prefix, robot_model, door_model, robot_src, door_src)


@dataclass(frozen=True)
class Timings:
    """Edge node settings scaled to the procedure duration."""

    poll_period: float
    mission_timeout: float
    call_timeout: float = 10.0

    @classmethod
    def of(cls, options: WarehouseOptions) -> Timings:
        return cls(max(0.02, min(0.5, options.duration / 5)), 30.0 + 20 * options.duration)


@contextmanager
def simulations(setup: Setup, robots: Sequence[str], options: WarehouseOptions) -> Iterator[list[Child]]:
    """The simulated robots (one process) and the door controller, started together."""
    repo = setup.example.parents[1]
    kind = robot_kind(options)
    sim_args = [sys.executable, "-m", kind.sim_module, *kind.sim_args(options.duration)]
    limit = str(options.timeout + 120)  # the simulations end by themselves should this process be killed
    sim_args += ["--prefix", str(setup.prefix), "--run-for", limit]
    for robot in robots:
        sim_args += ["--namespace", robot]
    children: list[Child] = []
    try:
        children.append(Child(f"the simulated {kind.label}", sim_args, repo, setup.work / "sim.log"))
        door_args = [sys.executable, "-m", "examples.warehouse.doorsim", "--door", DOOR, "--run-for", limit]
        children.append(Child("the simulated door", door_args, repo, setup.work / "doorsim.log"))
        for child in children:
            child.wait_for("ready", 60)
        yield children
    finally:
        for child in children:
            child.stop()


@contextmanager
def local_edge_nodes(setup: Setup, robots: Sequence[str], options: WarehouseOptions, broker: Any) -> Iterator[None]:
    """The robots' and the door's edge nodes in this process, on the in-process bus."""
    from td2adaptor.runtime.config import RuntimeConfig
    from td2adaptor.runtime.node.node import EdgeNode, RosOptions

    t = Timings.of(options)

    def config(robot: str, property_period: float) -> RuntimeConfig:
        return RuntimeConfig(
            robot=robot,
            property_period=property_period,
            poll_period=t.poll_period,
            mission_timeout=t.mission_timeout,
            call_timeout=t.call_timeout,
        )

    robot_configs = [config(r, 0.25) for r in robots]
    door_config = config(DOOR, 0.05)
    nodes = [
        EdgeNode(
            setup.robot_model,
            robot_configs,
            RosOptions(2, None, (setup.robot_src,), (setup.prefix,), node_name="warehouse_robots"),
            broker=broker,
        ),
        EdgeNode(
            setup.door_model,
            [door_config],
            RosOptions(2, None, (setup.door_src,), (setup.prefix,), node_name="warehouse_door"),
            broker=broker,
        ),
    ]
    try:
        for node in nodes:
            node.start()
        yield
    finally:
        for node in nodes:
            node.stop()


@contextmanager
def process_edge_nodes(setup: Setup, robots: Sequence[str], options: WarehouseOptions) -> Iterator[list[Child]]:
    """One `td2adaptor run` process per robot and one for the door, on the MQTT broker."""
    t = Timings.of(options)
    common = [
        "--bus",
        options.bus,
        "--prefix",
        str(setup.prefix),
        "--log-level",
        "info" if options.verbose else "warning",
    ]
    common += ["--poll-period", str(t.poll_period), "--mission-timeout", str(t.mission_timeout)]
    common += ["--call-timeout", str(t.call_timeout)]
    if options.allow_insecure:
        common.append("--allow-insecure")
    run = [sys.executable, "-m", "td2adaptor", "run"]
    robot_td = [str(setup.example / "td.json"), "-I", str(setup.example / "interfaces")]
    jobs = [
        (r, [*run, *robot_td, "--robot", r, "--package-path", str(setup.robot_src), "--property-period", "0.25"])
        for r in robots
    ]
    door = [*run, str(DOOR_TD), "--robot", DOOR, "--package-path", str(setup.door_src), "--property-period", "0.05"]
    jobs.append((DOOR, door))
    children: list[Child] = []
    try:
        for name, args in jobs:
            log = setup.work / f"edge-{name}.log"
            children.append(Child(f"the edge node of {name}", [*args, *common], setup.example.parents[1], log))
        yield children
    finally:
        for child in children:
            child.stop()


def open_behaviour_bus(options: WarehouseOptions, model: Model, broker: Any) -> Any:
    from td2adaptor.runtime.bus.bus import BusError
    from td2adaptor.runtime.bus.localbus import LocalBus

    if options.bus == "local":
        return LocalBus(broker, "warehouse-behaviour", clean_start=True)
    from td2adaptor.runtime.bus.mqttbus import MqttBus
    from td2adaptor.runtime.bus.security import SecurityError, parse_broker_url, plan_security

    try:
        address = parse_broker_url(options.bus)
        security = plan_security(model.thing.security, address, allow_insecure=options.allow_insecure)
    except SecurityError as exc:
        raise DemoError(str(exc)) from None
    bus = MqttBus(address, security, client_id=f"warehouse-behaviour-{os.getpid()}", clean_start=True)
    try:
        bus.connect()
    except BusError as exc:
        raise DemoError(str(exc)) from None
    return bus


def clear_retained(bus: Any, setup: Setup, robots: Sequence[str]) -> None:
    """Delete what an earlier run left retained on the broker (statuses, property values) for our things."""
    from td2adaptor.model.events import Kind, build_catalog

    for model, things in ((setup.robot_model, robots), (setup.door_model, [DOOR])):
        catalog = build_catalog(model)
        for thing in things:
            topics = [spec.topic(thing) for spec in catalog.specs if spec.kind in (Kind.PROPERTY, Kind.STATUS)]
            for topic in topics:
                bus.publish(topic, b"", retain=True)
    bus.flush(5.0)


@contextmanager
def stopped_by_sigterm() -> Iterator[None]:
    """SIGTERM ends the demo as an error does, through every clean-up on the way out: Python's default would
    end this process at once and leave its simulations and edge nodes running (they are not in its process
    group when a supervisor started it). In the main thread only, where signal handlers can be set."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(_signum: int, _frame: object) -> None:
        raise DemoError("stopped by SIGTERM before every cart was stored")

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run_warehouse(options: WarehouseOptions, out: Callable[[str], None] = print) -> bool:
    """Run the demo and print its summary; True when every cart was stored."""
    started = time.monotonic()
    kind = robot_kind(options)
    robots = list(kind.robot_ids[: options.robots])
    if options.bus != "local" and not options.bus.startswith(("mqtt://", "mqtts://")):
        raise DemoError(f"--bus {options.bus!r}: use local or mqtt://host:port")
    logging.basicConfig(level=logging.INFO if options.verbose else logging.ERROR, stream=sys.stderr)
    work = Path(tempfile.mkdtemp(prefix="td2adaptor-warehouse-"))

    def say(line: str) -> None:
        out(f"  {line}")

    try:
        with ExitStack() as stack:
            stack.enter_context(stopped_by_sigterm())  # left first: the simulations and edge nodes stop too
            setup = prepare(options, work, say)
            from td2adaptor.runtime.bus.localbus import LocalBroker

            broker = LocalBroker()
            behaviour_bus = open_behaviour_bus(options, setup.robot_model, broker)
            stack.callback(behaviour_bus.close)
            out(
                f"warehouse: {len(robots)} {kind.label} robot(s) ({', '.join(robots)}), door {DOOR}, "
                f"{len(CARTS)} carts, bus {options.bus}, procedures of {options.duration:g} s"
            )
            if options.bus != "local":
                clear_retained(behaviour_bus, setup, robots)
            stack.enter_context(simulations(setup, robots, options))
            edge_children: list[Child] = []
            if options.bus == "local":
                stack.enter_context(local_edge_nodes(setup, robots, options, broker))
            else:
                edge_children = stack.enter_context(process_edge_nodes(setup, robots, options))
            table = TaskTable(work / "tasks.db")
            table.create(CARTS)
            behaviour = BehaviourService(
                behaviour_bus,
                setup.robot_model,
                setup.door_model,
                robots,
                DOOR,
                table,
                door_front=DOOR_FRONT,
                mission_timeout=Timings.of(options).mission_timeout,
                log=say if options.verbose else (lambda _line: None),
                kind=kind.name,
            )
            behaviour.connect()
            missing = behaviour.wait_online(60.0)
            if missing:
                why = "; ".join(f"{c.name}: {c.why()}" for c in edge_children if c.proc.poll() is not None)
                raise DemoError(f"not online within 60 s: {', '.join(missing)}" + (f" ({why})" if why else ""))
            ready = time.monotonic()
            out(f"  start-up {ready - started:.1f} s; the behaviour service takes carts from {table.path.name}")
            remaining = max(1.0, options.timeout - (ready - started))
            results = behaviour.run(remaining)
            finished = time.monotonic()
            summary(out, results, behaviour, table, robots, started, ready, finished)
            failed = {r.robot for r in results if not r.moved}
            for child in edge_children:  # what the robot's edge node said last, for whoever reads the failure
                if any(child.name.endswith(f" {robot}") for robot in failed):
                    print(f"{child.name} logged last: {tail_of(child.log, 12)}", file=sys.stderr)
            return sum(r.moved for r in results) == len(CARTS)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def summary(
    out: Callable[[str], None],
    results: list[CartResult],
    behaviour: BehaviourService,
    table: TaskTable,
    robots: Sequence[str],
    started: float,
    ready: float,
    finished: float,
) -> None:
    for r in sorted(results, key=lambda r: r.cart.id):
        c = r.cart
        what = f"moved in {r.seconds:.1f} s" if r.moved else f"NOT moved: {r.failure}"
        out(f"  {c.id} (marker {c.marker}): {r.robot}  picking point {c.pick} -> storage {c.zone} {c.place}  {what}")
    states = table.states()
    untouched = [cart for cart, state in states.items() if state == "todo"]
    if untouched:
        out(f"  not taken: {', '.join(untouched)}")
    moved = sum(state == "moved" for state in states.values())
    out(f"carts moved: {moved}/{len(CARTS)}")
    parts = []
    for step, stats in behaviour.stats.items():
        parts.append(f"{step} {stats.per_action:.1f} (x{stats.count}: {stats.sent} sent, {stats.received} received)")
    out("bus messages per action: " + "; ".join(parts))
    out(
        f"bus messages: {behaviour.sent} sent, {behaviour.received} received by the behaviour service "
        f"({behaviour.property_events} of them property values)"
    )
    out(f"total time: {finished - started:.1f} s (start-up {ready - started:.1f} s, missions {finished - ready:.1f} s)")
