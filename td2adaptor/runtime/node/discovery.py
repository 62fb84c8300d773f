"""Registering a robot's Thing Description with a W3C WoT Discovery Thing Description Directory (TDD).

Optional (`directory` in the runtime configuration): the edge node `PUT`s the TD it publishes on the broker to
`<directory>/things/{id}` once the robot is online, and `DELETE`s it when it stops. The registered copy is the
published TD plus the discovery context and, with `directory_ttl`, a `registration.ttl` (WoT Discovery): the
node repeats the `PUT` every ttl/2 seconds, so the directory drops the TD of a node that died without stopping
(expiry) and gets it back after the directory itself restarted. `PUT` creates or replaces: a TD that changed
between two runs of a robot updates its registration. After the first `PUT` the node reads the TD back
(`GET /things/{id}`): a directory that stored it but cannot give it back as JSON (Domus 1.0.2, for a TD whose
RDF passes 128 KiB: docs/fleet.md) is reported in one warning, not left as a silently broken entry.

The directory is never in the way of the robot: registration runs on its own thread, failures are logged (the
URL without credentials, the directory's answer in short) and retried with exponential backoff, and stopping
waits for one short `DELETE` at most. Plain HTTP(S) with the standard library: no client dependency.
"""

from __future__ import annotations

import http.client
import json
import logging
import re
import ssl
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import quote

from td2adaptor.runtime.bus.security import redact_url

log = logging.getLogger("td2adaptor.runtime.discovery")

DISCOVERY_CONTEXT = "https://www.w3.org/2022/wot/discovery"
#: the registered TD's member that says whether the robot's ROS side is there (status.py), in td2adaptor's
#: namespace: a directory's query can then find the robots that are there now
PRESENCE_PREFIX, PRESENCE_NAMESPACE = "td2adaptor", "https://td2adaptor.dev/ns#"
PRESENCE_TERM = f"{PRESENCE_PREFIX}:presence"
TD_MEDIA_TYPE = "application/td+json"
PUT_TIMEOUT = 30.0  # a directory may take its time to store a large TD (it turns it into RDF)
DELETE_TIMEOUT = 5.0  # stopping waits at most this long for the directory
MAX_BACKOFF = 60.0


class DirectoryError(Exception):
    """A directory request failed; the message says which and why (never a credential)."""


def registration_document(td_text: str | bytes, ttl: int) -> dict[str, Any]:
    """The TD as registered: the published one with the discovery context and, when ttl > 0, its time to live."""
    td = json.loads(td_text)
    context = td.get("@context")
    contexts = list(context) if isinstance(context, list) else [context] if context is not None else []
    if DISCOVERY_CONTEXT not in contexts:
        contexts.append(DISCOVERY_CONTEXT)
    td["@context"] = contexts
    if ttl > 0:
        td["registration"] = {"ttl": ttl}
    return dict(td)


def backoff(attempt: int, base: float = 1.0, cap: float = MAX_BACKOFF) -> float:
    """Seconds to wait before retry `attempt` (1, 2, ...): doubling from `base`, at most `cap`."""
    return float(min(cap, base * 2 ** max(0, attempt - 1)))


@dataclass(frozen=True)
class Directory:
    """A Thing Description Directory's `/things` API, over HTTP(S) with the standard library."""

    url: str  # base URL, checked (config.check_directory_url)
    token: str | None = None  # Bearer token, if the directory wants one
    ca_file: str | None = None  # CA bundle for an https directory with a private CA

    def __repr__(self) -> str:  # the token stays out of logs and tracebacks
        return f"Directory({redact_url(self.url)!r})"

    def thing_url(self, thing_id: str) -> str:
        return f"{self.url}/things/{quote(thing_id, safe='')}"

    def request(
        self, method: str, thing_id: str, body: bytes | None, timeout: float, *, ok: tuple[int, ...] = ()
    ) -> int:
        """One request on /things/{id}; its HTTP status. Raises DirectoryError for no answer or an error status
        (other than those in `ok`)."""
        return self.exchange(method, thing_id, body, timeout, ok=ok)[0]

    def exchange(
        self, method: str, thing_id: str, body: bytes | None, timeout: float, *, ok: tuple[int, ...] = ()
    ) -> tuple[int, bytes]:
        """One request on /things/{id}; its HTTP status and answer. Raises DirectoryError for no answer or an
        error status (other than those in `ok`, answered with an empty body)."""
        headers = {"Accept": "application/json"}
        if body is not None:
            headers["Content-Type"] = TD_MEDIA_TYPE
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        target = self.thing_url(thing_id)
        req = urllib.request.Request(target, data=body, method=method, headers=headers)
        context = ssl.create_default_context(cafile=self.ca_file) if target.startswith("https:") else None
        where = f"{method} {redact_url(target)}"
        try:
            with urllib.request.urlopen(req, timeout=timeout, context=context) as resp:
                return int(resp.status), bytes(resp.read())
        except urllib.error.HTTPError as exc:
            if exc.code in ok:
                return int(exc.code), b""
            detail = _answer(exc)
            raise DirectoryError(f"{where}: the directory answered HTTP {exc.code} {exc.reason}{detail}") from None
        except (urllib.error.URLError, OSError, http.client.HTTPException) as exc:
            reason = exc.reason if isinstance(exc, urllib.error.URLError) else exc
            raise DirectoryError(f"{where}: no answer ({reason or type(exc).__name__})") from None

    def put(self, thing_id: str, document: Mapping[str, Any], timeout: float = PUT_TIMEOUT) -> int:
        """Create or replace the TD `thing_id` (201 created, 204 replaced)."""
        body = json.dumps(document, ensure_ascii=False).encode("utf-8")
        return self.request("PUT", thing_id, body, timeout)

    def get(self, thing_id: str, timeout: float = PUT_TIMEOUT) -> bytes:
        """The TD `thing_id` as the directory gives it back (JSON)."""
        return self.exchange("GET", thing_id, None, timeout)[1]

    def delete(self, thing_id: str, timeout: float = DELETE_TIMEOUT) -> int:
        """Remove the TD `thing_id` (404: it was not there, which is fine too)."""
        return self.request("DELETE", thing_id, None, timeout, ok=(404,))


def _answer(exc: urllib.error.HTTPError) -> str:
    """The start of an error answer's body (a directory says there why it refused), on one line."""
    try:
        text = exc.read(400).decode("utf-8", errors="replace")
    except OSError:
        return ""
    if text.lstrip().startswith("<"):  # an HTML error page (Flask's, Domus's): its words, not its markup
        text = re.sub(r"<[^>]*>?", " ", text)
    text = " ".join(text.split())
    return f": {text[:300]}" if text else ""


class Registration:
    """Keeps one robot's TD registered while the robot is online: `start()` registers (in the background,
    retrying), `stop()` deregisters. Timestamps and counts are kept for tests and the bench."""

    def __init__(
        self,
        directory: Directory,
        td_text: str | bytes,
        *,
        robot: str,
        ttl: int = 0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.directory = directory
        self.document = registration_document(td_text, ttl)
        self.thing_id = str(self.document.get("id") or "")
        if not self.thing_id:
            raise ValueError(f"robot {robot}: its Thing Description has no id, so a directory cannot hold it")
        self.robot = robot
        self.ttl = ttl
        self.clock = clock
        self.started_at: float | None = None
        self.registered_at: float | None = None  # the first successful PUT
        self.puts = 0  # successful PUTs (registrations and refreshes)
        self.failures = 0  # failed attempts in a row (0 once one succeeded)
        self.last_error: str | None = None
        self.readable: bool | None = None  # whether the directory gave the TD back after the first PUT
        self._stop = threading.Event()
        self._wake = threading.Event()  # set by stop() and by a presence to register now
        self._thread: threading.Thread | None = None

    @property
    def registration_seconds(self) -> float | None:
        """From start() to the directory holding the TD (None until it does)."""
        if self.started_at is None or self.registered_at is None:
            return None
        return self.registered_at - self.started_at

    def start(self) -> None:
        self.started_at = self.clock()
        self._thread = threading.Thread(target=self._run, name=f"td2adaptor-{self.robot}-directory", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            if self._register():
                wait = self.ttl / 2 if self.ttl > 0 else None  # refresh before the directory lets it expire
            else:
                wait = backoff(self.failures)
            self._wake.wait(wait)
            self._wake.clear()

    def reflect(self, presence: str | None) -> None:
        """The robot's ROS side is `presence` now (`present`, `partial`, `absent`): registered again at once
        with it (`td2adaptor:presence`), so that the directory says which robots are there."""
        if presence is None or self.document.get(PRESENCE_TERM) == presence:
            return
        document = dict(self.document)  # a new one: the registering thread may be sending the old one
        context = list(document["@context"])
        if not any(isinstance(c, Mapping) and PRESENCE_PREFIX in c for c in context):
            context.append({PRESENCE_PREFIX: PRESENCE_NAMESPACE})
        document["@context"], document[PRESENCE_TERM] = context, presence
        self.document = document
        self._wake.set()

    def _register(self) -> bool:
        try:
            status = self.directory.put(self.thing_id, self.document)
        except DirectoryError as exc:
            self.failures += 1
            self.last_error = str(exc)
            log.warning(
                "robot %s: could not register its Thing Description with the directory (attempt %d, retrying "
                "in %.0f s; the robot is served all the same): %s",
                self.robot,
                self.failures,
                backoff(self.failures),
                exc,
            )
            return False
        first = self.registered_at is None
        if first:
            self.registered_at = self.clock()
        elif self.failures:
            log.info("robot %s: registered with the directory again", self.robot)
        self.failures, self.last_error = 0, None
        self.puts += 1
        if first:
            log.info(
                "robot %s: Thing Description %s registered with %s (HTTP %d%s)",
                self.robot,
                self.thing_id,
                redact_url(self.directory.url),
                status,
                f", ttl {self.ttl} s" if self.ttl else "",
            )
            self._read_back()
        return True

    def _read_back(self) -> None:
        """GET the TD just registered: a directory that stored it but cannot give it back is reported once (the
        robot is served, and the registration kept, all the same)."""
        where = redact_url(self.directory.url)
        try:
            answer = self.directory.get(self.thing_id)
            back = json.loads(answer)
            if not isinstance(back, dict) or back.get("id") != self.thing_id:
                raise DirectoryError(f"GET {where}/things/...: the directory gave back a document without its id")
        except (DirectoryError, ValueError) as exc:
            self.readable = False
            reason = exc if isinstance(exc, DirectoryError) else "the directory's answer is not JSON"
            log.warning(
                "robot %s: the directory %s stored its Thing Description %s but cannot give it back: %s. The entry "
                "is stored and searchable there (SPARQL), but not readable as JSON (a directory such as Domus "
                "1.0.2 cannot give back a TD whose RDF passes 128 KiB; see docs/fleet.md)",
                self.robot,
                where,
                self.thing_id,
                reason,
            )
            return
        self.readable = True

    def stop(self) -> None:
        """Stop refreshing and remove the TD from the directory (one short attempt; its expiry is the fallback)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._wake.set()
        busy = False
        if self._thread is not None:
            self._thread.join(DELETE_TIMEOUT)  # a PUT under way may still land: remove it then too
            busy = self._thread.is_alive()
        if self.registered_at is None and not busy:
            return  # never got there: nothing to remove
        removed = self._delete()
        if busy and removed and self._thread is not None:
            # the PUT under way may land after that DELETE and store the TD again: once it is answered, remove again
            self._thread.join(PUT_TIMEOUT)
            if not self._thread.is_alive():
                self._delete(again=True)
        if removed:
            log.info("robot %s: Thing Description removed from the directory", self.robot)

    def _delete(self, *, again: bool = False) -> bool:
        """One DELETE; whether the directory holds the TD no more (404 counts). Failures are logged (not twice)."""
        try:
            self.directory.delete(self.thing_id)
            return True
        except DirectoryError as exc:
            if not again:
                expiry = f"; it expires after its ttl ({self.ttl} s)" if self.ttl else ""
                log.warning(
                    "robot %s: could not remove the Thing Description from the directory%s: %s",
                    self.robot,
                    expiry,
                    exc,
                )
            return False
