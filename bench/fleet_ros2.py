"""A fleet of simulated RB-1s on one broker (issue 17). Every figure is printed next to a baseline measured in the
same run: the same edge node serving one robot of the same simulated fleet.

One simulation process serves all the robots (examples/robotnik_rb1/sim/ros2.py --count N, on rclpy's
EventsExecutor), one mosquitto carries every robot's events, and the edge nodes run as `td2adaptor run`
processes in the deployments docs/fleet.md describes:

* `one process per robot`: N processes, each `td2adaptor run TD --robot fleet_i` (the fleet file's shared keys);
* `one process for the fleet`: one `td2adaptor run TD --config fleet.yaml` whose `robots:` lists all N;
* `--group-size K` (deployment `groups`): N/K processes, each a `robots:` list of K (docs/fleet.md's advice for
  a fleet one process cannot serve).

Figures per deployment:

* start-up: from launching the process(es) until every robot's retained status says online (its TD is retained
  before that), and until every robot finished a first goto mission (ROS discovery included);
* memory per robot: RSS of the edge-node process(es) / N, and PSS (shared libraries split between the
  processes that map them: the fair figure for N processes), and for one process what each robot after the
  first adds ((RSS - the 1-robot baseline's RSS) / (N - 1): the process's fixed part, an interpreter, rclpy and
  a DDS participant, paid once); the edge nodes run with the product's Fast DDS defaults
  (td2adaptor/runtime/ros/fastdds.xml), not the tests' profile the simulation loads; the threads of the edge
  node(s) at idle and the most seen under load;
* CPU of the edge node(s) at idle (no events; each robot's properties at most once a second: `property_mode:
  message` with `property_interval: 1`, as docs/fleet.md recommends for a fleet; `--property-mode sample` for
  the default sampling every second) and
  under 1 goto mission per second per robot (invoke → queued → running → finished feedback, polled every
  0.2 s), in % of one core; beside it the simulation's, and how busy the whole machine was (every process:
  broker, simulation and this bench's own MQTT client too, in % of all cores): latency tails grow long once
  the cores are nearly all busy, whichever process keeps them so;
* invoke event → first feedback event (`queued`, after the robot's `add` service answered), p50 and p99 over
  every mission of the load phase (target p99 <= 50 ms);
* lost feedback: each mission's terminal feedback carries its `seq`, so the feedback events it should have
  had are known; missing ones, and missions without a terminal event, are counted (target 0). Missions refused
  as `busy` (the previous one of that robot not finished yet) are counted apart.

Needs the ROS 2 extra and mosquitto. Run: `.venv/bin/python bench/fleet_ros2.py [--robots N] [--load S]`.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))
from runtime_bus import mosquitto  # noqa: E402

from td2adaptor.runtime.bus.bus import Message  # noqa: E402
from td2adaptor.runtime.bus.mqttbus import MqttBus  # noqa: E402
from td2adaptor.runtime.bus.security import parse_broker_url  # noqa: E402
from td2adaptor.runtime.ros.fastdds import USER_VARIABLES  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import EXAMPLE, Process, generate_rclpy  # noqa: E402

PREFIX = "fleet"  # robots fleet_0 ... fleet_<N-1>, each in ROS namespace fleet_i
GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}]}}
DURATION = 0.3  # seconds a simulated goto runs (after 0.05 s queued): a mission ends well within its second
POLL = 0.2  # the edge node's poll period (docs/fleet.md's example)
TICK = os.sysconf("SC_CLK_TCK")


# -- /proc ------------------------------------------------------------------------------------------------


def cpu_seconds(pids: Sequence[int]) -> float:
    """User + system CPU time of `pids` so far (a process that is gone counts 0)."""
    total = 0.0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += (int(fields[11]) + int(fields[12])) / TICK
    return total


def machine_busy() -> tuple[float, float]:
    """(busy, total) CPU seconds of the whole machine so far, all cores (/proc/stat: idle and iowait are not
    busy)."""
    fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    total = sum(fields[:8]) / TICK  # user nice system idle iowait irq softirq steal (guest is in user)
    return total - (fields[3] + fields[4]) / TICK, total


def machine_cpu(before: tuple[float, float]) -> float:
    """% of the machine's cores busy since `before` (machine_busy())."""
    busy, total = machine_busy()
    return 100 * (busy - before[0]) / max(total - before[1], 1e-9)


def threads(pids: Sequence[int]) -> int:
    """Threads of `pids` now, summed (a process that is gone counts 0)."""
    total = 0
    for pid in pids:
        try:
            total += len(os.listdir(f"/proc/{pid}/task"))
        except OSError:
            continue
    return total


def memory_kib(pids: Sequence[int]) -> tuple[int, int]:
    """(RSS, PSS) of `pids` in KiB, summed."""
    rss = pss = 0
    for pid in pids:
        try:
            for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
                if line.startswith("Rss:"):
                    rss += int(line.split()[1])
                elif line.startswith("Pss:"):
                    pss += int(line.split()[1])
        except OSError:
            continue
    return rss, pss


# -- the application side: one MQTT client watching every robot ---------------------------------------------


@dataclass
class Mission:
    robot: str
    sent: float
    first: float | None = None
    seqs: set[int] = field(default_factory=set)
    terminal_seq: int | None = None
    busy: bool = False


class Watcher:
    """Online robots and the feedback of every mission, by correlation (MQTT callbacks, one thread)."""

    def __init__(self, url: str) -> None:
        self.lock = threading.Condition()
        self.online: dict[str, float] = {}
        self.missions: dict[str, Mission] = {}
        self.bus = MqttBus(parse_broker_url(url), client_id=f"fleet-bench-{os.getpid()}", clean_start=True)
        self.bus.subscribe("td2adaptor/+/status", self._status)
        self.bus.subscribe("td2adaptor/+/GoToComponent/gotoRun/feedback", self._feedback)
        self.bus.connect()

    def _status(self, msg: Message) -> None:
        if not msg.payload:
            return
        event = json.loads(msg.payload)
        robot = msg.topic.split("/")[1]
        with self.lock:
            if event.get("payload", {}).get("state") == "online":
                self.online.setdefault(robot, time.perf_counter())
            else:
                self.online.pop(robot, None)
            self.lock.notify_all()

    def _feedback(self, msg: Message) -> None:
        now = time.perf_counter()
        event = json.loads(msg.payload)
        payload = event.get("payload") or {}
        with self.lock:
            m = self.missions.get(event.get("correlation", ""))
            if m is None:
                return
            if m.first is None:
                m.first = now
            m.seqs.add(int(payload.get("seq", 0)))
            if payload.get("terminal"):
                m.terminal_seq = int(payload.get("seq", 0))
                m.busy = payload.get("reason") == "busy"
                self.lock.notify_all()

    def forget_online(self) -> None:
        with self.lock:
            self.online.clear()

    def wait(self, predicate: Any, timeout: float) -> bool:
        with self.lock:
            return bool(self.lock.wait_for(predicate, timeout))

    def invoke(self, robot: str, correlation: str) -> None:
        with self.lock:
            self.missions[correlation] = Mission(robot, time.perf_counter())
        event = {"correlation": correlation, "payload": GOAL}
        self.bus.publish(f"td2adaptor/{robot}/GoToComponent/gotoRun", json.dumps(event).encode())

    def done(self, correlations: Sequence[str]) -> bool:
        return all(self.missions[c].terminal_seq is not None for c in correlations)

    def close(self) -> None:
        self.bus.close()


# -- one deployment ---------------------------------------------------------------------------------------


@dataclass
class Figures:
    robots: int
    processes: int
    online: float = 0.0
    startup_cpu: float = 0.0  # CPU seconds the edge node(s) used until every robot was online
    first_missions: float = 0.0
    rss_kib: int = 0
    pss_kib: int = 0
    threads_idle: int = 0  # threads of the edge node(s) once every robot finished a first mission
    threads_load: int = 0  # the most seen under load (sampled every half second)
    idle_cpu: float = 0.0  # % of one core
    load_cpu: float = 0.0
    sim_idle_cpu: float = 0.0
    sim_load_cpu: float = 0.0
    machine_idle_cpu: float = 0.0  # % of all cores, every process (broker, simulation, this bench included)
    machine_load_cpu: float = 0.0
    first_feedback: list[float] = field(default_factory=list)
    missions: int = 0
    busy: int = 0
    no_terminal: int = 0
    lost: int = 0
    load_start: float = 0.0  # wall-clock time (time.time()) the load phase began
    samples: list[tuple[float, float | None, str]] = field(default_factory=list)  # (sent, first feedback, robot)


class Deployment:
    def __init__(self, ctx: Context, robots: list[str], size: int, tag: str) -> None:
        self.ctx, self.robots, self.size, self.tag = ctx, robots, size, tag  # size: robots per process
        self.procs: list[subprocess.Popen[bytes]] = []
        self.logs = ctx.work / f"logs-{tag}"
        self.logs.mkdir(exist_ok=True)

    def start(self) -> None:
        c = self.ctx
        base = [
            sys.executable,
            "-m",
            "td2adaptor",
            "run",
            str(EXAMPLE / "td.json"),
            "-I",
            str(EXAMPLE / "interfaces"),
            "--prefix",
            str(c.prefix),
            "--package-path",
            str(c.src),
            "--log-level",
            "warning",
        ]
        if self.size == 1:
            runs = [(r, [*base, "--config", str(c.write_config(self.tag, None)), "--robot", r]) for r in self.robots]
        else:
            groups = [self.robots[i : i + self.size] for i in range(0, len(self.robots), self.size)]
            runs = [
                (f"{self.tag}-{i}", [*base, "--config", str(c.write_config(f"{self.tag}-{i}", group))])
                for i, group in enumerate(groups)
            ]
        for name, argv in runs:
            log = (self.logs / f"{name}.log").open("wb")
            self.procs.append(subprocess.Popen(argv, env=c.child_env, stdout=log, stderr=subprocess.STDOUT, cwd=REPO))
            log.close()

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in self.procs]

    def dead(self) -> list[str]:
        return [str(i) for i, p in enumerate(self.procs) if p.poll() is not None]

    def stop(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + 30
        for p in self.procs:
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(10)

    def tail(self) -> str:
        logs = sorted(self.logs.glob("*.log"))
        return "\n".join(f"{log.name}: {log.read_text(errors='replace')[-800:]}" for log in logs[:3])


@dataclass
class Context:
    work: Path
    prefix: Path
    src: Path
    url: str
    child_env: dict[str, str]
    watcher: Watcher
    sim: Process
    property_mode: str = "message"

    def write_config(self, tag: str, robots: list[str] | None) -> Path:
        state = self.work / f"state-{tag}"
        lines = [f"bus: {self.url}", f"poll_period: {POLL}", f"state_dir: {state}"]
        if self.property_mode == "message":  # each property at most once a second, as sampling would
            lines += ["property_mode: message", "property_interval: 1"]
        if robots is not None:
            lines.append("robots:")
            lines += [f"  - robot: {r}" for r in robots]
        path = self.work / f"{tag}.yaml"
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return path


def measure(ctx: Context, robots: list[str], size: int, tag: str, idle_s: float, load_s: float) -> Figures:
    w = ctx.watcher
    dep = Deployment(ctx, robots, size, tag)
    fig = Figures(len(robots), -(-len(robots) // size))
    sim_pid = [ctx.sim.proc.pid]
    w.forget_online()
    t0 = time.perf_counter()
    dep.start()
    try:
        if not w.wait(lambda: all(r in w.online for r in robots) or bool(dep.dead()), 600) or dep.dead():
            missing = [r for r in robots if r not in w.online]
            raise RuntimeError(f"{tag}: {len(missing)} robots not online, e.g. {missing[:3]}\n{dep.tail()}")
        fig.online = max(w.online[r] for r in robots) - t0
        fig.startup_cpu = cpu_seconds(dep.pids)
        warm = [f"{tag}-warm-{r}" for r in robots]
        for r, c in zip(robots, warm, strict=True):
            w.invoke(r, c)
        if not w.wait(lambda: w.done(warm), 120):
            raise RuntimeError(f"{tag}: first missions did not all end\n{dep.tail()}")
        fig.first_missions = time.perf_counter() - t0
        time.sleep(1.0)
        fig.rss_kib, fig.pss_kib = memory_kib(dep.pids)
        fig.threads_idle = threads(dep.pids)
        c0, s0, m0, t1 = cpu_seconds(dep.pids), cpu_seconds(sim_pid), machine_busy(), time.perf_counter()
        time.sleep(idle_s)
        dt = time.perf_counter() - t1
        fig.idle_cpu = 100 * (cpu_seconds(dep.pids) - c0) / dt
        fig.sim_idle_cpu = 100 * (cpu_seconds(sim_pid) - s0) / dt
        fig.machine_idle_cpu = machine_cpu(m0)
        # the load: one mission per robot per second, the robots' invokes spread evenly over each second
        sent: list[str] = []
        n = len(robots)
        c0, s0, m0, t1 = cpu_seconds(dep.pids), cpu_seconds(sim_pid), machine_busy(), time.perf_counter()
        fig.load_start = time.time() - (time.perf_counter() - t1)
        counted = t1
        for k in range(int(load_s * n)):
            due = t1 + k / n
            delay = due - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            if due - counted >= 0.5:
                counted = due
                fig.threads_load = max(fig.threads_load, threads(dep.pids))
            corr = f"{tag}-{k}"
            w.invoke(robots[k % n], corr)
            sent.append(corr)
        time.sleep(max(0.0, t1 + load_s - time.perf_counter()))
        dt = time.perf_counter() - t1
        fig.load_cpu = 100 * (cpu_seconds(dep.pids) - c0) / dt
        fig.sim_load_cpu = 100 * (cpu_seconds(sim_pid) - s0) / dt
        fig.machine_load_cpu = machine_cpu(m0)
        w.wait(lambda: w.done(sent), 15)
        with w.lock:
            missions = [w.missions[c] for c in sent]
        fig.missions = len(missions)
        for m in missions:
            fig.samples.append((m.sent - t1, None if m.first is None else m.first - m.sent, m.robot))
            if m.first is not None:
                fig.first_feedback.append(m.first - m.sent)
            if m.terminal_seq is None:
                fig.no_terminal += 1
                continue
            fig.busy += m.busy
            fig.lost += len(set(range(1, m.terminal_seq + 1)) - m.seqs)
    finally:
        dep.stop()
    return fig


# -- report ---------------------------------------------------------------------------------------------------


def pct(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def report(base: Figures, runs: list[tuple[str, Figures]]) -> None:
    print(f"{'':<44} {'baseline: 1 robot':>18}" + "".join(f" {name:>22}" for name, _ in runs))

    def row(label: str, fmt: str, get: Any, note: str = "") -> None:
        cells = "".join(f" {fmt.format(get(f)):>22}" for _, f in runs)
        print(f"{label:<44} {fmt.format(get(base)):>18}{cells}   {note}")

    ms = 1000.0
    row("robots / edge-node processes", "{}", lambda f: f"{f.robots} / {f.processes}")
    row("start-up: every robot online (TD retained)", "{:.1f} s", lambda f: f.online)
    row("start-up: every robot's first mission done", "{:.1f} s", lambda f: f.first_missions)
    row("start-up: CPU of the edge node(s) per robot", "{:.2f} s", lambda f: f.startup_cpu / f.robots)
    row("RSS per robot", "{:.1f} MiB", lambda f: f.rss_kib / 1024 / f.robots)
    row("PSS per robot", "{:.1f} MiB", lambda f: f.pss_kib / 1024 / f.robots)

    def added(f: Figures) -> str:
        """What each robot after the first adds to one process (its fixed part is the 1-robot baseline's)."""
        if f.processes != 1 or f.robots < 2:
            return "-"
        return f"{(f.rss_kib - base.rss_kib) / 1024 / (f.robots - 1):.1f} MiB"

    row("RSS per robot added to one process", "{}", added, "(RSS - the 1-robot process's RSS) / (robots - 1)")
    row("threads of the edge node(s), idle / load", "{}", lambda f: f"{f.threads_idle} / {f.threads_load}")
    row("CPU at idle, edge node(s)", "{:.1f} %", lambda f: f.idle_cpu, "% of one core")
    row("CPU at idle per robot", "{:.2f} %", lambda f: f.idle_cpu / f.robots)
    row("CPU at 1 mission/s per robot, edge node(s)", "{:.1f} %", lambda f: f.load_cpu)
    row("CPU at 1 mission/s, per robot", "{:.2f} %", lambda f: f.load_cpu / f.robots)
    row("CPU of the simulation, idle / load", "{}", lambda f: f"{f.sim_idle_cpu:.0f} / {f.sim_load_cpu:.0f} %")
    row(
        "machine busy (every process), idle / load",
        "{}",
        lambda f: f"{f.machine_idle_cpu:.0f} / {f.machine_load_cpu:.0f} %",
        f"% of all {os.cpu_count()} cores (broker, simulation, this bench too)",
    )
    row("missions (busy refusals)", "{}", lambda f: f"{f.missions} ({f.busy})")
    row("invoke -> 1st feedback p50", "{:.1f} ms", lambda f: pct(f.first_feedback, 0.5) * ms)
    row("invoke -> 1st feedback p99", "{:.1f} ms", lambda f: pct(f.first_feedback, 0.99) * ms, "target <= 50 ms")
    row("lost feedback (+ missions with no terminal)", "{}", lambda f: f"{f.lost} + {f.no_terminal}", "target 0")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", type=int, default=100, help="robots in the fleet (default 100)")
    parser.add_argument("--idle", type=float, default=5.0, help="seconds of the idle CPU measurement")
    parser.add_argument("--load", type=float, default=15.0, help="seconds of 1 mission/s per robot")
    parser.add_argument(
        "--deployment",
        choices=("both", "process", "fleet", "groups"),
        default="both",
        help="which deployments to measure (both: process and fleet)",
    )
    parser.add_argument("--group-size", type=int, default=25, help="robots per process of the groups deployment")
    parser.add_argument(
        "--property-mode",
        choices=("message", "sample"),
        default="message",
        help="message (with property_interval 1, docs/fleet.md's advice) or sample (property_period 1)",
    )
    parser.add_argument(
        "--dump",
        type=Path,
        help="write every load-phase mission (seconds since the load began, invoke -> first feedback) as JSON, "
        "to find when the slow ones happen",
    )
    args = parser.parse_args()
    if not env.ros2_available():
        print("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh): skipped")
        return
    if shutil.which("mosquitto") is None and not Path("/usr/sbin/mosquitto").exists():
        print("mosquitto not installed: skipped")
        return
    env.isolate()
    prefix = build_interfaces()
    work = Path(tempfile.mkdtemp(prefix="td2adaptor-bench-fleet-"))
    src = generate_rclpy(EXAMPLE / "td.json", work / "src")
    robots = [f"{PREFIX}_{i}" for i in range(args.robots)]
    print(
        f"python {sys.version.split()[0]}, {time.strftime('%Y-%m-%d')}, {os.cpu_count()} cores, "
        f"{args.robots} robots, load {args.load:g} s at 1 mission/s per robot, idle {args.idle:g} s, "
        f"property_mode {args.property_mode}"
    )
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a stopped bench stops its children too
    child_env = env.child_env([prefix])
    # Fast DDS's shared-memory transport hangs some of 100 participants starting at once on a busy machine (a
    # port's interprocess mutex times out after 2 s and is broken, eProsima/Fast-DDS#6117: 15 of 100 edge
    # nodes never finished starting); UDP has no such lock. rmw_fastrtps (Jazzy) picks the transports itself
    # (loopback UDP and shared memory) under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, whatever
    # FASTDDS_BUILTIN_TRANSPORTS or an XML profile say: the fleet's processes discover over the subnet range
    # instead, on the private domain id env.isolate() claimed
    child_env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
    child_env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    sim_argv = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--namespace", PREFIX]
    sim_argv += ["--count", str(args.robots), "--duration", str(DURATION), "--rate", "1", "--quiet"]
    sim_argv += ["--executor", "events"]
    with mosquitto() as url:
        sim = Process(sim_argv, child_env)
        watcher = Watcher(url)
        try:
            sim.wait_for(lambda e: e.get("event") == "ready", 120)
            # the edge nodes run with the product's Fast DDS defaults (td2adaptor/runtime/ros/fastdds.xml), not
            # the tests' discovery profile the simulation uses
            edge_env = {k: v for k, v in child_env.items() if k not in USER_VARIABLES}
            ctx = Context(work, prefix, src, url, edge_env, watcher, sim, args.property_mode)
            base = measure(ctx, robots[:1], 1, "base", args.idle, args.load)
            runs = []
            if args.deployment in ("both", "process"):
                runs.append(("one process per robot", measure(ctx, robots, 1, "procs", args.idle, args.load)))
            if args.deployment in ("both", "fleet"):
                runs.append(("one process, fleet", measure(ctx, robots, len(robots), "fleet", args.idle, args.load)))
            if args.deployment == "groups":
                k = max(1, args.group_size)
                label = f"{k} robots per process"
                runs.append((label, measure(ctx, robots, k, f"groups{k}", args.idle, args.load)))
        finally:
            watcher.close()
            sim.stop()
    report(base, runs)
    if args.dump is not None:
        dumped = {
            name: {"load_start": f.load_start, "missions": [list(sample) for sample in f.samples]}
            for name, f in [("baseline", base), *runs]
        }
        args.dump.write_text(json.dumps(dumped), encoding="utf-8")
    print(f"(median first feedback, baseline: {statistics.median(base.first_feedback) * 1000:.1f} ms)")
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
