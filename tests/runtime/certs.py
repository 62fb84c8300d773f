"""A throw-away CA with a server certificate (for 127.0.0.1) and a client certificate, made with openssl."""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest


@dataclass(frozen=True)
class Certs:
    ca: Path
    server_cert: Path
    server_key: Path
    client_cert: Path
    client_key: Path


def _run(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def make_certs(root: Path) -> Certs:
    if shutil.which("openssl") is None:
        pytest.fail("openssl is not installed: run `SUDO= bash .ci/setup-mqtt.sh`")
    root.mkdir(parents=True, exist_ok=True)
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    _run(
        "req",
        "-x509",
        *ec,
        "-keyout",
        "ca.key",
        "-out",
        "ca.pem",
        "-subj",
        "/CN=td2adaptor test CA",
        "-days",
        "2",
        cwd=root,
    )
    (root / "server.ext").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n", encoding="utf-8")
    for name, ext in (("server", ["-extfile", "server.ext"]), ("client", [])):
        _run("req", *ec, "-keyout", f"{name}.key", "-out", f"{name}.csr", "-subj", f"/CN={name}", cwd=root)
        sign = ["-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial", "-days", "2", *ext]
        _run("x509", "-req", "-in", f"{name}.csr", "-out", f"{name}.pem", *sign, cwd=root)
    for key in root.glob("*.key"):
        key.chmod(0o600)
    return Certs(root / "ca.pem", root / "server.pem", root / "server.key", root / "client.pem", root / "client.key")
