"""Helpers shared by the ROS 2 tests and their fixtures (no fixtures here, so test modules may import it)."""

from __future__ import annotations

import json
import queue
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import td2adaptor
from td2adaptor.backends.registry import load as load_backend
from td2adaptor.compiler.pipeline import Result
from td2adaptor.diagnostics import Diagnostics, Severity
from td2adaptor.generation.backend import GenOptions
from tests import generated
from tests.ros2 import env
from tests.tools import missing

EXAMPLE = env.REPO / "examples" / "robotnik_rb1"
PACKAGE = "robotnik_rb_1_adaptor"
SIM_NAMESPACES = ("rb1_base_a", "rb1_base_b", "rb1_base_c", "rb1_base_d", "rb1_base_e", "rb1_base_f")
SIM_DURATION = 1.0

Errors = type[BaseException] | tuple[type[BaseException], ...]


def answered(call: Callable[[], object], lost: Errors, answer: Errors = ()) -> bool:
    """Whether the robot answered `call` (a side-effect free request; `answer`: failures that are answers too).

    A ROS 2 service can be discovered by a client before its server has discovered the client's response
    reader; the server's first answers are then lost (Fast DDS drops them after 100 ms; more likely on a loaded
    machine: docs/binding.md). A test that relies on a call's first answer waits for one answered request,
    `until(lambda: answered(...))`; the readers of one client node are announced together, so one answered
    call says the others are known too."""
    try:
        call()
    except answer:
        return True
    except lost:
        return False
    return True


def require_ros2() -> None:
    """The `ros2` extra, by the one policy (tests/tools.py: a skip here, a failure in CI)."""
    if env.ros2_available():
        return
    missing("ROS 2 Jazzy wheels not installed (bash .ci/setup-ros2.sh, or pip install -e '.[ros2]')")


def generate_rclpy(td: Path, out: Path, *, package_name: str | None = None) -> Path:
    """Run the rclpy backend on `td` (RB-1 interfaces) and write the tree; the package directory."""
    return build_rclpy(td, out, package_name=package_name)[1]


def build_rclpy(
    td: Path, out: Path, *, interfaces: Path = EXAMPLE / "interfaces", package_name: str | None = None
) -> tuple[Result, Path]:
    """Compile `td` against `interfaces`, run the rclpy backend and write its tree under `out`: the compile
    result (its model is never None) and the package directory."""
    result = td2adaptor.compile(td, interfaces=[interfaces])
    assert result.model is not None, [d.message for d in result.diagnostics]
    diags = Diagnostics()
    tree = load_backend("rclpy").generate(result.model, GenOptions(package_name=package_name), diags)
    assert not [d for d in diags if d.severity is Severity.ERROR], [d.message for d in diags]
    generated.write(tree, out)
    return result, out / (package_name or result.model.package_name)


class Process:
    """A child process whose stdout is JSON event lines (the simulated robot, the silent server)."""

    def __init__(self, args: list[str], environ: dict[str, str]) -> None:
        # stderr goes to a file: a pipe nobody reads could fill up and stall the child
        self.stderr = tempfile.TemporaryFile(mode="w+", encoding="utf-8")
        self.proc = subprocess.Popen(
            args, env=environ, stdout=subprocess.PIPE, stderr=self.stderr, text=True, cwd=env.REPO
        )
        self.events: queue.Queue[dict[str, Any]] = queue.Queue()
        self.seen: list[dict[str, Any]] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            try:
                self.events.put(json.loads(line))
            except ValueError:
                continue

    def wait_for(self, match: Callable[[dict[str, Any]], bool], timeout: float) -> dict[str, Any]:
        """The first event (seen before or arriving within `timeout`) that `match` accepts."""
        for event in self.seen:
            if match(event):
                return event
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            try:
                event = self.events.get(timeout=min(remaining, 0.1))
            except queue.Empty:
                if self.proc.poll() is not None and self.events.empty():
                    break
                continue
            self.seen.append(event)
            if match(event):
                return event
        raise AssertionError(f"no matching event within {timeout} s (exit {self.proc.poll()}): {self.stderr_tail()}")

    def stderr_tail(self, size: int = 2000) -> str:
        """The end of what the child wrote to stderr so far (for a failure's message)."""
        self.stderr.seek(0)
        return self.stderr.read()[-size:]

    def drain(self) -> list[dict[str, Any]]:
        """Every event seen so far, those waiting in the queue included."""
        while True:
            try:
                self.seen.append(self.events.get_nowait())
            except queue.Empty:
                return list(self.seen)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        self.stderr.close()


def std_td(*, sensors: bool = True) -> dict[str, Any]:
    """A small TD on standard interfaces only (std_srvs, geometry_msgs, sensor_msgs): other shapes than RB-1's.

    `StdComponent` runs with the PyPI wheels (std_srvs, geometry_msgs); `SensorComponent` uses sensor_msgs
    (fixed-size and numeric arrays), which is only type-checked here.
    """

    def form(name: str, rtype: str, op: str | list[str], **extra: Any) -> list[dict[str, Any]]:
        href = "ros:" + name.removeprefix("/{{robotName}}/")
        return [{"href": href, "op": op, "rosv:name": name, "rosv:type": rtype, **extra}]

    read = ["readproperty", "observeproperty"]
    write = ["writeproperty"]
    actions = {
        "trigger": ("StdComponent", "/{{robotName}}/trigger", "std_srvs/srv/Trigger"),
        "enable": ("StdComponent", "/{{robotName}}/enable", "std_srvs/srv/SetBool"),
        "reset": ("SensorComponent", "/reset", "std_srvs/srv/Empty"),
    }
    properties = {
        "cmd": ("StdComponent", "/{{robotName}}/cmd_vel", "geometry_msgs/msg/Twist", write),
        "initialPose": (
            "StdComponent",
            "/{{robotName}}/initialpose",
            "geometry_msgs/msg/PoseWithCovarianceStamped",
            write,
        ),
        "scan": ("SensorComponent", "/{{robotName}}/scan", "sensor_msgs/msg/LaserScan", read),
        "imu": ("SensorComponent", "/{{robotName}}/imu", "sensor_msgs/msg/Imu", read),
        "image": ("SensorComponent", "/{{robotName}}/image", "sensor_msgs/msg/Image", write),
    }
    td: dict[str, Any] = {
        "@context": ["https://www.w3.org/2022/wot/td/v1.1", "https://td2adaptor.dev/ns/rosv/v1"],
        "@type": "Thing",
        "title": "Std Bot",
        "description": "Standard interfaces only.",
        "securityDefinitions": {"nosec_sc": {"scheme": "nosec"}},
        "security": ["nosec_sc"],
        "actions": {
            key: {"rosv:component": comp, "forms": form(name, rtype, "invokeaction")}
            for key, (comp, name, rtype) in actions.items()
        },
        "properties": {},
    }
    for key, (comp, name, rtype, op) in properties.items():
        flags = {"observable": True, "readOnly": True} if op is read else {"writeOnly": True}
        td["properties"][key] = {"rosv:component": comp, **flags, "forms": form(name, rtype, op)}
    td["properties"]["scan"]["forms"][0]["rosv:qos"] = {"reliability": "best_effort", "depth": 5}
    if not sensors:
        for group in ("actions", "properties"):
            td[group] = {k: v for k, v in td[group].items() if v["rosv:component"] != "SensorComponent"}
    return td
