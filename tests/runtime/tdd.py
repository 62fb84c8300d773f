"""A real W3C WoT Thing Description Directory on loopback: the Eclipse Thingweb Domus TDD API on an Oxigraph
SPARQL server, both from PyPI (pinned in .ci/tdd-requirements.txt, installed into .cache/tdd/venv by
.ci/setup-tdd.sh). Without that environment (or node, which Domus runs for JSON-LD), tests skip saying why.

Oxigraph rather than rdflib-endpoint: Domus sends every SPARQL request with a fixed 5 s timeout, and
rdflib-endpoint spends ~10 s of CPU parsing the update that stores the RB-1's TD (2,139 triples), so a robot
could never register; Oxigraph's /sparql endpoint takes queries and updates on one URL as Domus needs, in well
under a second. Domus 1.0.2 hands a stored TD's N-Triples to node as one command-line argument to frame it
as JSON again, so it cannot give back as JSON a TD whose N-Triples exceed Linux's 128 KiB argument limit (the
full RB-1's: ~167 KiB): the JSON round-trip tests use a robot with fewer affordances (`small_robot_td`), and
the full RB-1's registration is read back as RDF (`triples`).
"""

from __future__ import annotations

import json
import os
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any
from urllib.parse import quote

from tests.conftest import REPO
from tests.ports import free_port
from tests.tools import missing, require

VENV = REPO / ".cache" / "tdd" / "venv"
SETUP = "bash .ci/setup-tdd.sh"


def require_tdd() -> Path:
    """The directory's environment, or (tests/tools.py) a skip saying how to get it."""
    if not (VENV / "bin" / "flask").is_file() or not (VENV / "bin" / "oxigraph").is_file():
        missing(f"no Thing Description Directory installed in {VENV.relative_to(REPO)} ({SETUP})")
    require("node", "apt install nodejs")
    return VENV


class TddServer:
    """Oxigraph (in memory) and Domus on free loopback ports, run from `workdir` (empty: Domus would read a
    config.toml there). `clear_period`: seconds between Domus's sweeps of expired TDs."""

    def __init__(self, workdir: Path, *, clear_period: int = 1) -> None:
        self.venv = require_tdd()
        self.dir = workdir
        self.dir.mkdir(parents=True, exist_ok=True)
        self.sparql_port = free_port()
        self.port = free_port()
        self.clear_period = clear_period
        self.procs: list[subprocess.Popen[bytes]] = []
        self.logs: list[Path] = []

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def _spawn(self, name: str, args: list[str], env: dict[str, str]) -> None:
        log = self.dir / f"{name}.log"
        self.logs.append(log)
        with log.open("wb") as out:
            self.procs.append(subprocess.Popen(args, cwd=self.dir, env=env, stdout=out, stderr=subprocess.STDOUT))

    def start(self, timeout: float = 90.0) -> None:
        bin_dir = self.venv / "bin"
        env = {k: v for k, v in os.environ.items() if not k.startswith("TDD__")}
        env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
        self._spawn("oxigraph", [str(bin_dir / "oxigraph"), "serve", "--bind", f"127.0.0.1:{self.sparql_port}"], env)
        domus = {
            **env,
            "TDD__SPARQLENDPOINT_URL": f"http://127.0.0.1:{self.sparql_port}/sparql",
            "TDD__TD_REPO_URL": self.url,
            "TDD__OVERWRITE_DISCOVERY": "true",  # its bundled discovery context: nothing fetched
            "TDD__PERIOD_CLEAR_EXPIRE_TD": str(self.clear_period),
        }
        args = [str(bin_dir / "flask"), "--app", "tdd", "run", "--host", "127.0.0.1", "--port", str(self.port)]
        self._spawn("domus", args, domus)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(p.poll() is not None for p in self.procs):
                break
            try:
                if self.status("GET", "/things") == 200:
                    return
            except OSError:
                pass
            time.sleep(0.2)
        output = self.output()
        self.stop()
        raise RuntimeError(f"the TD directory did not start within {timeout} s:\n{output}")

    def domus_log(self) -> str:
        """What Domus printed so far (its sweeps of expired TDs among it)."""
        return (self.dir / "domus.log").read_text(errors="replace")

    def output(self) -> str:
        """The end of both servers' output, for failure messages."""
        return "\n".join(f"--- {log.name}\n{log.read_text(errors='replace')[-3000:]}" for log in self.logs)

    def stop(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs:
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        self.procs = []

    # -- the directory's API, as a consumer uses it ------------------------------------------------------------

    def status(self, method: str, path: str) -> int:
        req = urllib.request.Request(self.url + path, method=method)
        try:
            with urllib.request.urlopen(req, timeout=30) as resp:
                return int(resp.status)
        except urllib.error.HTTPError as exc:
            return int(exc.code)

    def ids(self) -> list[str]:
        """The ids of the TDs the directory lists (GET /things). Domus answers 500 to a listing that meets a TD
        being replaced or swept away (a KeyError of its own): asked again then, a few times."""
        for attempt in range(10):
            try:
                with urllib.request.urlopen(self.url + "/things", timeout=30) as resp:
                    return [td["id"] for td in json.loads(resp.read())]
            except urllib.error.HTTPError as exc:
                if exc.code != 500 or attempt == 9:
                    raise
                time.sleep(0.2)
        raise AssertionError("unreachable")

    def thing(self, thing_id: str) -> dict[str, Any] | None:
        """GET /things/{id}: the TD, or None when the directory has none (404; expired: Domus answers "" and,
        once swept, a document without id).
        Domus replaces a TD by deleting and inserting it: during a refresh, a reader may briefly get None."""
        try:
            with urllib.request.urlopen(f"{self.url}/things/{quote(thing_id, safe='')}", timeout=30) as resp:
                value = json.loads(resp.read())
        except urllib.error.HTTPError as exc:
            if exc.code == 404:
                return None
            raise
        # after its sweep of an expired TD, Domus 1.0.2 answers an empty shell (no id: only its own
        # registration data), having left the TD's metadata behind
        return value if isinstance(value, dict) and "id" in value else None

    def triples(self, thing_id: str) -> str | None:
        """GET /things/{id} as N-Triples (the stored RDF, which Domus gives back whatever the TD's size), or None
        for a 404."""
        url = f"{self.url}/things/{quote(thing_id, safe='')}"
        req = urllib.request.Request(url, headers={"Accept": "application/n-triples"})
        try:
            with urllib.request.urlopen(req, timeout=60) as resp:
                return str(resp.read().decode("utf-8"))
        except urllib.error.HTTPError as exc:
            if exc.code == 404:
                return None
            raise


def small_robot_td(tmp: Path) -> Path:
    """The RB-1 TD with one component (GoTo: run/query/cancel) and the door: a whole robot the simulation
    serves, small enough for Domus to give back (see the module docstring)."""
    from tests.conftest import EXAMPLE

    td = json.loads((EXAMPLE / "td.json").read_text(encoding="utf-8"))
    td["properties"] = {k: v for k, v in td["properties"].items() if k == "door"}
    td["actions"] = {k: v for k, v in td["actions"].items() if k.startswith("goto")}
    path = tmp / "small-rb1.td.json"
    path.write_text(json.dumps(td, indent=2), encoding="utf-8")
    return path


def semantic(value: Any) -> Any:
    """A TD as its RDF graph keeps it, for comparing a TD with the one a directory gives back: JSON-LD arrays
    are sets there (order lost, a one-element array the same as its element, an empty one the same as none),
    numbers are doubles. Only the shape changes: every key and value must still be there."""
    if isinstance(value, dict):
        return {k: semantic(v) for k, v in value.items() if v != []}
    if isinstance(value, list):
        items = sorted((semantic(v) for v in value), key=lambda v: json.dumps(v, sort_keys=True))
        return items[0] if len(items) == 1 else items
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    return value


def as_registered(td: dict[str, Any]) -> dict[str, Any]:
    """A TD the directory gave back, without what the directory adds: its registration information and the
    discovery context."""
    out = {k: v for k, v in td.items() if k != "registration"}
    context = out.get("@context")
    if isinstance(context, list):
        out["@context"] = [c for c in context if c != "https://www.w3.org/2022/wot/discovery"]
    return out
