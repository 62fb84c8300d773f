"""Real ROS 1 for tests: a private rosmaster on a free loopback port, the simulated RB-1, client scripts.

The pytest interpreter cannot import Debian's rospy, so every ROS 1 process runs under /usr/bin/python3 with
PYTHONPATH = the genpy modules of the RB-1 interfaces + the generated package's src/ (one init_node each).
"""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import sys
import time
import xmlrpc.client
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.ports import free_port

REPO = Path(__file__).resolve().parents[2]
SYSTEM_PYTHON = "/usr/bin/python3"
SIM = REPO / "examples" / "robotnik_rb1" / "sim" / "ros1.py"
HERE = Path(__file__).resolve().parent


def ros1_problem() -> str | None:
    """Why real ROS 1 cannot run here (None when it can)."""
    if not Path(SYSTEM_PYTHON).is_file():
        return f"{SYSTEM_PYTHON} not found"
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import rospy, rosmaster, genpy, catkin_pkg"], capture_output=True, text=True
    )
    if probe.returncode != 0:
        return "Debian's rospy is not installed: run `SUDO= bash .ci/setup-ros1.sh` (or sudo)"
    missing = [tool for tool in ("catkin_make", "rosrun", "roslaunch") if shutil.which(tool) is None]
    if missing:
        return f"{', '.join(missing)} not on PATH: run `SUDO= bash .ci/setup-ros1.sh` (or sudo)"
    return None


def interfaces_dir() -> Path:
    """The genpy modules of the RB-1 interfaces (built once, cached by content, safe under xdist)."""
    out = subprocess.run([SYSTEM_PYTHON, str(SIM), "--print-interfaces"], capture_output=True, text=True, check=True)
    return Path(out.stdout.strip().splitlines()[-1])


def ros_env(uri: str, home: Path, *pythonpath: Path) -> dict[str, str]:
    """A clean environment for a ROS 1 process on the private master."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ROS_", "PYTHON"))}
    env.update(
        ROS_MASTER_URI=uri,
        ROS_IP="127.0.0.1",
        ROS_HOSTNAME="127.0.0.1",
        ROS_HOME=str(home),
        ROS_LOG_DIR=str(home / "log"),
        PYTHONPATH=os.pathsep.join(str(p) for p in pythonpath),
        PYTHONUNBUFFERED="1",
        PYTHONDONTWRITEBYTECODE="1",
    )
    return env


@dataclass
class Master:
    uri: str
    home: Path
    process: subprocess.Popen[bytes]

    def env(self, *pythonpath: Path) -> dict[str, str]:
        return ros_env(self.uri, self.home, *pythonpath)


@contextmanager
def rosmaster(home: Path) -> Iterator[Master]:
    """`rosmaster --core` on a free port; ready when getSystemState answers."""
    home.mkdir(parents=True, exist_ok=True)
    for _attempt in range(5):
        port = free_port()
        uri = f"http://127.0.0.1:{port}/"
        env = ros_env(uri, home)
        proc = subprocess.Popen(
            ["rosmaster", "--core", "-p", str(port), "-w", "3"],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and proc.poll() is None:
            try:
                with xmlrpc.client.ServerProxy(uri) as master:
                    answer: Any = master.getSystemState("/probe")
                if answer[0] == 1:
                    break
            except OSError:
                time.sleep(0.02)
        else:
            _stop(proc)
            continue
        try:
            yield Master(uri, home, proc)
        finally:
            _stop(proc)
        return
    raise RuntimeError("rosmaster did not start")


def _stop(proc: subprocess.Popen[Any]) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    for stream in (proc.stdin, proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()


@dataclass
class Sim:
    """A ROS node process whose stdout lines are read with a deadline."""

    process: subprocess.Popen[bytes]
    lines: list[str]
    buffer: bytes = b""

    def read_until(self, prefix: str, timeout: float) -> str:
        """The next stdout line starting with `prefix` (lines before it are kept in `lines`)."""
        deadline = time.monotonic() + timeout
        assert self.process.stdout is not None
        fd = self.process.stdout.fileno()
        while True:
            while b"\n" in self.buffer:
                raw, self.buffer = self.buffer.split(b"\n", 1)
                line = raw.decode("utf-8", "replace")
                self.lines.append(line)
                if line.startswith(prefix):
                    return line
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            ready, _, _ = select.select([fd], [], [], remaining)
            if not ready:
                break
            chunk = os.read(fd, 65536)
            if not chunk:
                break
            self.buffer += chunk
        raise AssertionError(f"no line starting with {prefix!r} from {self.process.args!r}; got {self.lines}")


@contextmanager
def run_sim(master: Master, interfaces: Path, namespace: str, *extra: str) -> Iterator[Sim]:
    proc = subprocess.Popen(
        [SYSTEM_PYTHON, str(SIM), "--namespace", namespace, *extra],
        env=master.env(interfaces),
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    sim = Sim(proc, [])
    try:
        sim.read_until("ready", 20.0)
        yield sim
    finally:
        _stop(proc)


@contextmanager
def run_server(master: Master, interfaces: Path, script: str, *args: str) -> Iterator[subprocess.Popen[bytes]]:
    """A helper ROS node from tests/ros1/ that prints `ready` when it is up."""
    proc = subprocess.Popen(
        [SYSTEM_PYTHON, str(HERE / script), *args],
        env=master.env(interfaces),
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    try:
        Sim(proc, []).read_until("ready", 20.0)
        yield proc
    finally:
        _stop(proc)


def run_client(master: Master, pythonpath: Sequence[Path], code: str, timeout: float = 60.0) -> Any:
    """Run `code` under Debian's Python with rospy initialised; it must print one JSON line last."""
    prelude = (
        "import json, time, rospy\n"
        "rospy.init_node('td2adaptor_test_client', anonymous=True, disable_signals=True)\n"
        "def emit(value):\n"
        "    print(json.dumps(value), flush=True)\n"
    )
    out = subprocess.run(
        [SYSTEM_PYTHON, "-c", prelude + code],
        env=master.env(*pythonpath),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    if out.returncode != 0:
        raise AssertionError(f"client failed ({out.returncode}):\n{out.stdout}\n{out.stderr}")
    lines = [line for line in out.stdout.splitlines() if line.strip()]
    if not lines:
        raise AssertionError(f"client printed nothing:\n{out.stderr}")
    return json.loads(lines[-1])


def run_system_python(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([SYSTEM_PYTHON, "-c", code, *args], capture_output=True, text=True, timeout=60)


if __name__ == "__main__":  # pragma: no cover - manual check
    print(ros1_problem() or "ROS 1 ready", file=sys.stderr)
