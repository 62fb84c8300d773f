"""A throw-away CA with a server certificate (for 127.0.0.1) and a client certificate, made with openssl; and
more server certificates of that CA with other names or validity dates (`server_cert`), to see each refusal."""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

from tests.tools import require


@dataclass(frozen=True)
class Certs:
    ca: Path
    server_cert: Path
    server_key: Path
    client_cert: Path
    client_key: Path


def _run(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


_EC = ("-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes")


def make_certs(root: Path) -> Certs:
    require("openssl", "run `SUDO= bash .ci/setup-mqtt.sh`")
    root.mkdir(parents=True, exist_ok=True)
    _run(
        "req",
        "-x509",
        *_EC,
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
        _run("req", *_EC, "-keyout", f"{name}.key", "-out", f"{name}.csr", "-subj", f"/CN={name}", cwd=root)
        sign = ["-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial", "-days", "2", *ext]
        _run("x509", "-req", "-in", f"{name}.csr", "-out", f"{name}.pem", *sign, cwd=root)
    for key in root.glob("*.key"):
        key.chmod(0o600)
    return Certs(root / "ca.pem", root / "server.pem", root / "server.key", root / "client.pem", root / "client.key")


def server_cert(certs: Certs, name: str, *, san: str, start: str, end: str) -> tuple[Path, Path]:
    """Another server certificate of `certs`' CA, `name`.pem and `name`.key beside it: for the names of `san`
    (e.g. `DNS:localhost`), valid from `start` to `end` (openssl's YYYYMMDDHHMMSSZ; `openssl ca` is the tool
    that takes dates, dates in the past or future included)."""
    root = certs.ca.parent
    work = root / f"{name}.ca"
    work.mkdir()
    (work / "index.txt").touch()
    (work / "serial").write_text("01\n", encoding="utf-8")
    (work / "ca.cnf").write_text(
        "[ca]\ndefault_ca = test\n[test]\ndatabase = index.txt\nnew_certs_dir = .\nserial = serial\n"
        "default_md = sha256\npolicy = any\nunique_subject = no\n[any]\ncommonName = supplied\n"
        f"[ext]\nsubjectAltName = {san}\n",
        encoding="utf-8",
    )
    _run("req", *_EC, "-keyout", f"../{name}.key", "-out", "req.csr", "-subj", f"/CN={name}", cwd=work)
    _run(
        "ca",
        "-batch",
        "-config",
        "ca.cnf",
        "-cert",
        str(certs.ca),
        "-keyfile",
        str(root / "ca.key"),
        "-in",
        "req.csr",
        "-out",
        f"../{name}.pem",
        "-startdate",
        start,
        "-enddate",
        end,
        "-extensions",
        "ext",
        "-notext",
        cwd=work,
    )
    (root / f"{name}.key").chmod(0o600)
    return root / f"{name}.pem", root / f"{name}.key"
