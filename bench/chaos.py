"""Chaos run of the edge node (issue 30): real mosquitto, the simulated RB-1 on real ROS 2, `td2adaptor run`.

Two phases against one `td2adaptor run` process serving a fleet from the RB-1 Thing Model:

* **bad events**: at least 5,000 malformed or refusable events (not JSON, not objects, nested thousands deep,
  non-finite numbers, float32 overflow, lone surrogates, wrong envelope members, malformed and stale times,
  reused ids, too large, retained commands), on the envelope topics and on the WoT topics of one robot, one at a
  time. Each must get an answer (an error event, on the WoT error topic for a WoT message) and none may reach
  the robot (the simulation prints every service call it serves and every door command it receives);
* **missions through faults**: the other robots run goto missions back to back (each command with an id and a
  time, as docs/security.md asks) while faults come in turn: the broker restarted, the edge process killed
  with SIGKILL and started again, the simulation killed with SIGKILL and started again. Every mission must end
  with exactly one terminal feedback event (a mission whose command was resent after a silence counts once),
  its feedback numbered without a gap.

Prints the figures and exits 1 when any bad event went unanswered or reached the robot, or any mission has no
terminal event or more than one. Needs the ROS 2 extra and mosquitto (`bash .ci/setup.sh --test`).
Run: `.venv/bin/python bench/chaos.py [--bad 5000] [--missions 60] [--robots 3]`.
"""

from __future__ import annotations

import argparse
import json
import random
import signal
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from td2adaptor.model.events import build_catalog  # noqa: E402
from td2adaptor.model.wot import wot_topic  # noqa: E402
from tests.ros2 import env  # noqa: E402
from tests.ros2.build import build_interfaces  # noqa: E402
from tests.ros2.common import EXAMPLE, Process  # noqa: E402
from tests.runtime.broker import Mosquitto, mosquitto_binary  # noqa: E402
from tests.runtime.client import AppClient  # noqa: E402
from tests.runtime.edge import RunProcess, until  # noqa: E402
from tests.runtime.rb1 import rb1_model  # noqa: E402

GOAL = {"procedure": {"goals": [{"pose": {"x": 1.0, "y": 2.0, "theta": 0.0}}]}}
BAD_ROBOT = "chaos_bad"
ANSWER_TIMEOUT = 3.0
MAX_EVENT_BYTES = 65536  # the node's default limit
NUMBER = "@number@"  # stands for a number literal JSON cannot hold as a float (replaced in the text)


def stamp(offset: float = 0.0) -> str:
    moment = datetime.now(timezone.utc) + timedelta(seconds=offset)
    return moment.isoformat(timespec="milliseconds").replace("+00:00", "Z")


# -- the bad events ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Bad:
    category: str
    topic: str
    payload: bytes
    wot: bool
    retain: bool = False


def _nest(depth: int, inner: str = "1") -> str:
    return "[" * depth + inner + "]" * depth


def _nest_object(depth: int) -> str:
    return '{"a":' * depth + "1" + "}" * depth


def bad_events(robot: str, count: int, seed: int) -> Iterator[Bad]:
    """`count` events the node must refuse (every one answered, none run), drawn from the categories below."""
    rng = random.Random(seed)
    catalog = build_catalog(rb1_model())
    specs = list(catalog.inbound())
    invoke = next(s for s in specs if s.affordance == "gotoRun")
    query = next(s for s in specs if s.affordance == "gotoQuery")
    write = next(s for s in specs if s.kind.value == "write")
    env_topic = {s.affordance: s.topic(robot) for s in specs}
    wot = {s.affordance: wot_topic(s, robot) for s in specs}
    n = 0

    def ident() -> str:
        nonlocal n
        n += 1
        return f"bad-{seed}-{n}"

    def envelope(spec: Any, payload: Any = None, **members: Any) -> dict[str, Any]:
        event: dict[str, Any] = {"id": ident(), "time": stamp(), "correlation": f"c-{n}"}
        if spec.kind.value == "invoke":
            event["payload"] = GOAL if payload is None else payload
        elif spec.kind.value == "write":
            event["payload"] = {"data": 0.5} if payload is None else payload
        event.update(members)
        return event

    def text(event: Any) -> bytes:
        return json.dumps(event, ensure_ascii=True).encode()

    deep = [100, 500, 989, 990, 1000, 5000, 100000]
    bad_times = [
        "2019-13-01T00:00:00Z",
        "2020-02-30T00:00:00Z",
        "2021-01-01T24:00:00Z",
        "2021-01-01T00:00:00+99:99",
        "2021-01-01T00:00:60Z",
        "yesterday",
        "2021-01-01",
        "",
    ]
    float_paths = ["x", "y", "theta"]

    def goal_with(field_name: str) -> dict[str, Any]:
        """GOAL with `literal` (a JSON number text) as the value of pose field `field_name` (see `number`)."""
        pose: dict[str, Any] = {"x": 1.0, "y": 2.0, "theta": 0.0, field_name: NUMBER}
        return {"procedure": {"goals": [{"pose": pose}]}}

    def number(event: Any, literal: str) -> bytes:
        return text(event).replace(f'"{NUMBER}"'.encode(), literal.encode())

    makers: list[tuple[str, bool, Callable[[], tuple[str, bytes, bool]]]] = [
        # -- envelope topics
        (
            "not-json",
            False,
            lambda: (env_topic[rng.choice(list(env_topic))], rng.randbytes(rng.randint(1, 64)) + b"\xff", False),
        ),
        ("not-json", False, lambda: (env_topic["gotoRun"], b'{"id": "x", ', False)),
        (
            "not-json",
            False,
            lambda: (env_topic["gotoRun"], rng.choice([b"NaN", b"Infinity", b"-Infinity", b"{'a':1}"]), False),
        ),
        (
            "not-object",
            False,
            lambda: (
                env_topic[rng.choice(list(env_topic))],
                rng.choice([b"[]", b"1", b'"s"', b"true", b"null"]),
                False,
            ),
        ),
        ("deep", False, lambda: (env_topic["gotoRun"], _nest(rng.choice(deep)).encode(), False)),
        (
            "deep",
            False,
            lambda: (
                env_topic["gotoRun"],
                text(envelope(invoke))[:-1] + b',"extra":' + _nest_object(rng.choice(deep)).encode() + b"}",
                False,
            ),
        ),
        (
            "non-finite",
            False,
            lambda: (
                env_topic["gotoRun"],
                number(envelope(invoke, goal_with(rng.choice(float_paths))), rng.choice(["1e400", "-1e400", "1e309"])),
                False,
            ),
        ),
        (
            "non-finite",
            False,
            lambda: (env_topic["door"], number(envelope(write, {"data": NUMBER}), "1e400"), False),
        ),
        (
            "surrogate",
            False,
            lambda: (
                env_topic["gotoRun"],
                text(envelope(invoke, **{rng.choice(["correlation", "id"]): "x\ud800y"})),
                False,
            ),
        ),
        (
            "surrogate",
            False,
            lambda: (
                env_topic["gotoRun"],
                text(
                    envelope(
                        invoke,
                        {
                            "procedure": {
                                "goals": [
                                    {"header": {"frame_id": "\udfff"}, "pose": {"x": 1.0, "y": 0.0, "theta": 0.0}}
                                ]
                            }
                        },
                    )
                ),
                False,
            ),
        ),
        ("bad-time", False, lambda: (env_topic["gotoRun"], text(envelope(invoke, time=rng.choice(bad_times))), False)),
        (
            "stale-time",
            False,
            lambda: (env_topic["gotoRun"], text(envelope(invoke, time=stamp(-rng.uniform(301, 10**6)))), False),
        ),
        (
            "future-time",
            False,
            lambda: (env_topic["gotoRun"], text(envelope(invoke, time=stamp(rng.uniform(31, 10**6)))), False),
        ),
        (
            "bad-member",
            False,
            lambda: (
                env_topic[rng.choice(["gotoRun", "gotoQuery", "gotoCancel"])],
                text(
                    {
                        **envelope(query),
                        **rng.choice(
                            [
                                {"id": 5},
                                {"time": 5},
                                {"correlation": ""},
                                {"correlation": "c" * 300},
                                {"correlation": {"a": 1}},
                                {"mission": "seven"},
                                {"mission": 2**70},
                                {"mission": 1.5},
                                {"type": "feedback"},
                                {"robot": "someone_else"},
                                {"unknown_member": 1},
                            ]
                        ),
                    }
                ),
                False,
            ),
        ),
        (
            "bad-payload",
            False,
            lambda: (
                env_topic["gotoRun"],
                text(envelope(invoke, rng.choice([[], "go", 5, {"procedure": 1}, {"nope": {}}]))),
                False,
            ),
        ),
        (
            "too-large",
            False,
            lambda: (env_topic["gotoRun"], b'{"pad":"' + b"x" * (MAX_EVENT_BYTES + 10) + b'"}', False),
        ),
        ("retained", False, lambda: (env_topic[rng.choice(["gotoCancel", "gotoQuery"])], text(envelope(query)), True)),
        # -- WoT topics
        ("not-json", True, lambda: (wot[rng.choice(list(wot))], rng.randbytes(rng.randint(1, 64)) + b"\xff", False)),
        (
            "not-object",
            True,
            lambda: (
                wot[rng.choice(["gotoRun", "gotoQuery", "gotoCancel"])],
                rng.choice([b"[]", b"1", b'"s"', b"true"]),
                False,
            ),
        ),
        ("deep", True, lambda: (wot["gotoRun"], _nest(rng.choice(deep)).encode(), False)),
        (
            "deep",
            True,
            lambda: (wot["gotoRun"], ('{"procedure":' + _nest_object(rng.choice(deep)) + "}").encode(), False),
        ),
        (
            "non-finite",
            True,
            lambda: (
                wot["gotoRun"],
                number(goal_with(rng.choice(float_paths)), rng.choice(["1e400", "-1e400"])),
                False,
            ),
        ),
        ("non-finite", True, lambda: (wot["door"], b'{"data": 1e400}', False)),
        ("surrogate", True, lambda: (wot["gotoRun"], json.dumps({**GOAL, "correlationId": "a\ud800"}).encode(), False)),
        (
            "bad-member",
            True,
            lambda: (
                wot["gotoQuery"],
                text(rng.choice([{"mission": "seven"}, {"mission": 1.5}, {"other": 1}, {"correlationId": ""}])),
                False,
            ),
        ),
        (
            "bad-payload",
            True,
            lambda: (
                wot["gotoRun"],
                text(rng.choice([{"procedure": 1}, {"nope": {}}, {"procedure": {"goals": "x"}}])),
                False,
            ),
        ),
        ("too-large", True, lambda: (wot["gotoRun"], b'{"pad":"' + b"x" * (MAX_EVENT_BYTES + 10) + b'"}', False)),
        ("retained", True, lambda: (wot["gotoQuery"], b'{"mission": 1}', True)),
    ]
    for _ in range(count):
        category, is_wot, make = rng.choice(makers)
        topic, payload, retain = make()
        yield Bad(category, topic, payload, is_wot, retain)


def run_bad_phase(app: AppClient, sim: Process, count: int, seed: int) -> dict[str, Any]:
    robot = BAD_ROBOT
    envelope_answers = (f"td2adaptor/{robot}/error",)
    wot_answers = (f"td2adaptor/{robot}/wot-thing/error",)
    outcome: dict[str, Any] = {
        "sent": 0,
        "answered": 0,
        "unanswered": Counter(),
        "by_category": Counter(),
        "examples": [],
    }
    ran_before = robot_calls(sim, robot)
    with app.cond:
        first = len(app.events)
    for bad in bad_events(robot, count, seed):
        with app.cond:
            mark = len(app.events)
        info = app.client.publish(bad.topic, bad.payload, qos=1, retain=bad.retain)
        info.wait_for_publish(10)
        wanted = wot_answers if bad.wot else envelope_answers

        def answered(events: list[Any], mark: int = mark, wanted: tuple[str, ...] = wanted) -> bool:
            return any(t in wanted for t, _ in events[mark:])

        with app.cond:
            ok = app.cond.wait_for(lambda: answered(app.events), ANSWER_TIMEOUT)
        outcome["sent"] += 1
        outcome["by_category"][f"{'wot' if bad.wot else 'envelope'} {bad.category}"] += 1
        if ok:
            outcome["answered"] += 1
        else:
            outcome["unanswered"][f"{'wot' if bad.wot else 'envelope'} {bad.category}"] += 1
            if len(outcome["examples"]) < 8:
                outcome["examples"].append((bad.topic, bad.payload[:120]))
        if bad.retain:  # clear it as docs/security.md says; the clearing message must not be answered
            app.client.publish(bad.topic, b"", qos=1, retain=True).wait_for_publish(10)
    time.sleep(1.0)
    with app.cond:  # every bad event has exactly one envelope error event (the WoT error mirrors it)
        errors = sum(1 for t, _ in app.events[first:] if t in envelope_answers)
    outcome["extra"] = errors - outcome["sent"]
    outcome["robot_calls"] = robot_calls(sim, robot)
    outcome["robot_calls"].subtract(ran_before)
    outcome["robot_calls"] = +outcome["robot_calls"]
    outcome["door_commands"] = sum(1 for e in drain(sim) if e.get("event") == "door")
    return outcome


_sim_seen: list[dict[str, Any]] = []


def drain(sim: Process) -> list[dict[str, Any]]:
    while True:
        try:
            _sim_seen.append(sim.events.get_nowait())
        except Exception:
            return _sim_seen


def robot_calls(sim: Process, robot: str) -> Counter[str]:
    """The service calls the simulation served for `robot`, by operation (add = a mission started)."""
    return Counter(str(e.get("op")) for e in drain(sim) if e.get("event") == "call" and e.get("robot") == robot)


class App(AppClient):
    """The application: the robots' outbound events (every answer), whatever they hold."""

    PATTERNS = [
        "td2adaptor/+/error",
        "td2adaptor/+/status",
        "td2adaptor/+/+/+/feedback",
        "td2adaptor/+/+/+/state",
        "td2adaptor/+/wot-thing/error",
        "td2adaptor/+/wot-thing/+/+/feedback",
        "td2adaptor/+/wot-thing/+/+/state",
    ]

    def __init__(self, url: str) -> None:
        super().__init__(url, self.PATTERNS, client_id="chaos-app")

    def _on_message(self, client: Any, userdata: Any, msg: Any) -> None:
        try:
            super()._on_message(client, userdata, msg)
        except (ValueError, RecursionError):  # an answer the node should never send: kept as raw text
            with self.cond:
                self.events.append((msg.topic, {"raw": bytes(msg.payload[:200]).decode(errors="replace")}))
                self.cond.notify_all()


# -- missions through faults -------------------------------------------------------------------------------


@dataclass
class MissionLog:
    sent: int = 0
    resent: int = 0
    terminal: Counter[str] = field(default_factory=Counter)
    outcomes: Counter[str] = field(default_factory=Counter)
    gaps: int = 0
    lost: list[str] = field(default_factory=list)


def terminals(app: AppClient, correlation: str) -> list[dict[str, Any]]:
    with app.cond:
        fb = [e for t, e in app.events if e.get("type") == "feedback" and e.get("correlation") == correlation]
    unique = {e["id"]: e for e in fb}  # a QoS 1 redelivery repeats an event (same id), never adds one
    return [e for e in unique.values() if e["payload"].get("terminal")]


def drive(app: AppClient, robot: str, missions: int, log: MissionLog, stop: threading.Event) -> None:
    for i in range(missions):
        if stop.is_set():
            return
        correlation = f"{robot}-{i}"
        command = {"id": correlation, "time": stamp(), "correlation": correlation, "payload": GOAL}
        topic = f"td2adaptor/{robot}/GoToComponent/gotoRun"
        app.send(topic, command, while_offline=True)
        log.sent += 1
        ended = lambda c=correlation: bool(terminals(app, c))  # noqa: E731
        if not until(ended, 20.0, 0.05):
            log.resent += 1  # what a user does after a silence: send the same command again (same id and time)
            app.send(topic, command, while_offline=True)
            until(ended, 40.0, 0.05)
        ends = terminals(app, correlation)
        log.terminal[str(len(ends))] += 1
        if not ends:
            log.lost.append(correlation)
            continue
        payload = ends[0]["payload"]
        log.outcomes[f"{payload.get('state')}/{payload.get('reason', '-')}"] += 1


def seq_gaps(app: AppClient, correlations: list[str]) -> int:
    """Missions whose feedback numbers (by event id, redeliveries removed) are not 1..n."""
    gaps = 0
    with app.cond:
        fb = [e for _, e in app.events if e.get("type") == "feedback"]
    by: dict[str, dict[str, int]] = {}
    for e in fb:
        by.setdefault(str(e.get("correlation")), {})[e["id"]] = e["payload"].get("seq", 0)
    for corr in correlations:
        seqs = sorted(by.get(corr, {}).values())
        if seqs and seqs != list(range(1, len(seqs) + 1)):
            gaps += 1
    return gaps


# -- set-up ------------------------------------------------------------------------------------------------


def start_sim(prefix: Path, robots: list[str]) -> Process:
    args = [sys.executable, "-m", "examples.robotnik_rb1.sim.ros2", "--duration", "0.5", "--queue-time", "0.05"]
    for robot in robots:
        args += ["--namespace", robot]
    process = Process(args, env.child_env([prefix]))
    process.wait_for(lambda e: e.get("event") == "ready", timeout=60)
    return process


def start_edge(prefix: Path, fleet: Path) -> RunProcess:
    package = REPO / "generated" / "rclpy" / "robotnik_rb_1_adaptor"
    args = [str(EXAMPLE / "rb1.tm.json"), "-I", str(EXAMPLE / "interfaces"), "--config", str(fleet), "--ros", "2"]
    args += ["--package-path", str(package), "--prefix", str(prefix)]
    run = RunProcess(args, env=env.child_env([prefix]))
    run.wait_ready(120)
    return run


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bad", type=int, default=5000, help="bad events to send (default 5000)")
    parser.add_argument("--missions", type=int, default=60, help="missions per robot (default 60)")
    parser.add_argument("--robots", type=int, default=3, help="robots running missions (default 3)")
    parser.add_argument("--fault-every", type=float, default=6.0, help="seconds between faults (default 6)")
    parser.add_argument("--seed", type=int, default=30)
    args = parser.parse_args()
    if not env.ros2_available():
        print("skipped: the ROS 2 extra is not installed (bash .ci/setup.sh --test)")
        return 0
    try:
        mosquitto_binary()
    except Exception:
        print("skipped: mosquitto is not installed (bash .ci/setup.sh --test)")
        return 0
    env.isolate()
    prefix = build_interfaces()
    robots = [f"chaos_{i}" for i in range(args.robots)]
    with tempfile.TemporaryDirectory(prefix="td2adaptor-chaos-") as tmp:
        broker = Mosquitto(Path(tmp) / "broker")
        broker.start()
        fleet = Path(tmp) / "fleet.yaml"
        lines = [
            f"bus: {broker.url}",
            "poll_period: 0.05",
            "property_period: 0",
            "call_timeout: 5",
            "mission_timeout: 60",
        ]
        lines += [f"state_dir: {tmp}/state", "robots:"]
        lines += [f"  - {{robot: {r}}}" for r in [*robots, BAD_ROBOT]]
        fleet.write_text("\n".join(lines) + "\n", encoding="utf-8")
        sim = start_sim(prefix, [*robots, BAD_ROBOT])
        edge = start_edge(prefix, fleet)
        app = App(broker.url)
        faults: Counter[str] = Counter()
        try:
            started = time.monotonic()
            bad = run_bad_phase(app, sim, args.bad, args.seed)
            bad_seconds = time.monotonic() - started
            print(
                f"bad events: {bad['sent']} sent in {bad_seconds:.1f} s, {bad['answered']} answered, "
                f"{sum(bad['unanswered'].values())} unanswered, {bad['extra']} answers beyond one each; "
                f"calls reaching the robot {dict(bad['robot_calls'])}, "
                f"door commands {bad['door_commands']}"
            )
            for category, sent in sorted(bad["by_category"].items()):
                print(f"  {category:<24} {sent:>5} sent, {bad['unanswered'][category]:>4} unanswered")
            for topic, payload in bad["examples"]:
                print(f"  unanswered: {topic} {payload!r}")
            with app.cond:  # the mission phase looks at its own events only
                app.events.clear()

            logs = {r: MissionLog() for r in robots}
            stop = threading.Event()
            drivers = [
                threading.Thread(target=drive, args=(app, r, args.missions, logs[r], stop), daemon=True) for r in robots
            ]
            for t in drivers:
                t.start()
            kinds = ["broker restart", "edge SIGKILL", "simulation SIGKILL"]
            k = 0
            while any(t.is_alive() for t in drivers):
                if stop.wait(args.fault_every) or not any(t.is_alive() for t in drivers):
                    break
                kind = kinds[k % len(kinds)]
                k += 1
                faults[kind] += 1
                if kind == "broker restart":
                    broker.stop()
                    time.sleep(1.0)
                    broker.start()
                elif kind == "edge SIGKILL":
                    edge.proc.send_signal(signal.SIGKILL)
                    edge.proc.wait(10)
                    time.sleep(1.0)
                    edge = start_edge(prefix, fleet)
                else:
                    sim.proc.send_signal(signal.SIGKILL)
                    sim.proc.wait(10)
                    sim.stop()
                    time.sleep(1.0)
                    sim = start_sim(prefix, [*robots, BAD_ROBOT])
            for t in drivers:
                t.join(120)
            total = MissionLog()
            for log in logs.values():
                total.sent += log.sent
                total.resent += log.resent
                total.terminal.update(log.terminal)
                total.outcomes.update(log.outcomes)
                total.lost += log.lost
            correlations = [f"{r}-{i}" for r in robots for i in range(args.missions)]
            total.gaps = seq_gaps(app, correlations)
            print(f"faults: {dict(faults)} over {time.monotonic() - started - bad_seconds:.0f} s")
            print(
                f"missions: {total.sent} sent ({total.resent} resent after 20 s of silence); terminal events per "
                f"mission: {dict(sorted(total.terminal.items()))}; feedback numbering gaps: {total.gaps}"
            )
            print(f"  outcomes: {dict(total.outcomes.most_common())}")
            if total.lost:
                print(f"  no terminal event: {total.lost[:10]}")
        finally:
            app.close()
            edge.terminate()
            sim.stop()
            broker.stop()
    failed = (
        sum(bad["unanswered"].values()) > 0
        or bad["extra"] != 0
        or sum(bad["robot_calls"].values()) > 0
        or bad["door_commands"] > 0
        or bool(total.lost)
        or any(n not in ("1",) for n in total.terminal)
        or total.gaps > 0
    )
    print("verdict:", "FAILED" if failed else "passed")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
