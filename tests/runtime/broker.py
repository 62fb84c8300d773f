"""A real mosquitto broker on a free loopback port, configured in a temporary directory."""

from __future__ import annotations

import getpass
import os
import shutil
import socket
import subprocess
import time
from pathlib import Path

import pytest

from tests.ports import free_port
from tests.tools import missing


def mosquitto_binary() -> str:
    found = shutil.which("mosquitto") or next(
        (p for p in ("/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto") if os.access(p, os.X_OK)), None
    )
    if found is None:
        missing("mosquitto is not installed: run `SUDO= bash .ci/setup-mqtt.sh` (or .ci/setup.sh --test)")
    return found


class Mosquitto:
    """One broker process; `restart()` keeps its port and, unless `persistence` is off, its sessions and
    retained messages."""

    mqtt_version = "5"

    def __init__(
        self,
        workdir: Path,
        *,
        users: dict[str, str] | None = None,
        tls: tuple[Path, Path, Path] | None = None,
        anonymous: bool | None = None,
        acl: Path | None = None,
        require_certificate: bool = True,
        identity_as_username: bool = False,
        extra: tuple[str, ...] = (),
        persistence: bool = True,
    ) -> None:
        self.dir = workdir
        self.dir.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        self.users = users
        self.proc: subprocess.Popen[bytes] | None = None
        self.conf = self.dir / "mosquitto.conf"
        lines = [
            f"listener {self.port} 127.0.0.1",
            *extra,  # more of the listener's settings (e.g. max_connections), right after it
            f"user {getpass.getuser()}",
            f"persistence {'true' if persistence else 'false'}",  # false: a restart forgets sessions, retained
            f"persistence_location {self.dir}/",
            f"log_dest file {self.dir}/mosquitto.log",
            "log_type error",
            "log_type warning",
            "log_type notice",
            "max_queued_messages 100000",
            "set_tcp_nodelay true",
            "max_inflight_messages 100",
        ]
        if tls is not None:  # (CA, server certificate, server key); clients present a certificate if required
            ca, cert, key = tls
            lines += [f"cafile {ca}", f"certfile {cert}", f"keyfile {key}"]
            lines.append(f"require_certificate {'true' if require_certificate else 'false'}")
            if identity_as_username:  # the client certificate's CN is the user: no password needed
                lines.append("use_identity_as_username true")
        if users is None:
            lines.append(f"allow_anonymous {'false' if anonymous is False else 'true'}")
        else:
            passwd = self.dir / "passwd"
            passwd.touch(mode=0o600)
            for name, password in users.items():
                subprocess.run(["mosquitto_passwd", "-b", str(passwd), name, password], check=True, capture_output=True)
            lines += [f"allow_anonymous {'true' if anonymous else 'false'}", f"password_file {passwd}"]
        if acl is not None:
            lines.append(f"acl_file {acl}")
        self.conf.write_text("\n".join(lines) + "\n", encoding="utf-8")

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self, timeout: float = 10.0) -> None:
        self.proc = subprocess.Popen(
            [mosquitto_binary(), "-c", str(self.conf)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                err = self.proc.stderr.read().decode() if self.proc.stderr else ""
                log = (self.dir / "mosquitto.log").read_text() if (self.dir / "mosquitto.log").exists() else ""
                raise RuntimeError(f"mosquitto exited with {self.proc.returncode}: {err}{log}")
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.2):
                    return
            except OSError:
                time.sleep(0.02)
        raise RuntimeError(f"mosquitto did not listen on {self.port} within {timeout} s")

    def stop(self) -> None:
        """A clean shutdown (SIGTERM): mosquitto saves its sessions and queued messages."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
        if proc.stderr:
            proc.stderr.close()

    def restart(self) -> None:
        self.stop()
        self.start()


AMQTT = Path(__file__).resolve().parents[2] / ".cache" / "amqtt" / "venv" / "bin" / "amqtt"


class Amqtt:
    """An amqtt broker (a second, independent MQTT 3.1.1 implementation, in Python) with Mosquitto's interface,
    anonymous access only. It speaks MQTT 3.1.1 only, and keeps sessions in memory: a restart loses them
    (see docs/brokers.md)."""

    mqtt_version = "3.1.1"

    def __init__(self, workdir: Path) -> None:
        if not AMQTT.exists():
            pytest.fail("amqtt is not installed: run `bash .ci/setup-amqtt.sh` (or .ci/setup.sh --test)")
        self.dir = workdir
        self.dir.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        self.proc: subprocess.Popen[bytes] | None = None
        self.conf = self.dir / "amqtt.yaml"
        self.log = self.dir / "amqtt.log"
        self.conf.write_text(
            "listeners:\n"
            "  default:\n"
            "    type: tcp\n"
            f"    bind: 127.0.0.1:{self.port}\n"
            "    max_connections: 1000\n"
            "plugins:\n"
            "  amqtt.plugins.authentication.AnonymousAuthPlugin:\n"
            "    allow_anonymous: true\n",
            encoding="utf-8",
        )

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self, timeout: float = 20.0) -> None:
        with self.log.open("ab") as log:
            self.proc = subprocess.Popen([str(AMQTT), "-c", str(self.conf)], stdout=log, stderr=log)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"amqtt exited with {self.proc.returncode}: {self.log.read_text()[-2000:]}")
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.2):
                    return
            except OSError:
                time.sleep(0.05)
        raise RuntimeError(f"amqtt did not listen on {self.port} within {timeout} s")

    def stop(self) -> None:
        proc, self.proc = self.proc, None
        if proc is None:
            return
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)

    def restart(self) -> None:
        self.stop()
        self.start()


Broker = Mosquitto | Amqtt
