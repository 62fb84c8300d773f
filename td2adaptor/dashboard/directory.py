"""Robots from a W3C WoT Thing Description Directory as well as from the bus (`dashboard --directory URL`): the
directory's listing (`GET <directory>/things`) read every `period` seconds, each TD's robot told by the topics
its forms name (`<root>/<robot>/...`). A robot's retained TD on the bus wins over its directory copy (the
directory gives back JSON-LD re-framed from RDF, and may keep a TD until its ttl after the robot is gone); a
robot listed only there shows with the status the bus says, or none. The token (`TD2ADAPTOR_DIRECTORY_TOKEN`)
and CA file (`TD2ADAPTOR_DIRECTORY_CA_FILE`) are the edge node's; failures are logged (the URL redacted) and
retried at the next period, never in the dashboard's way."""

from __future__ import annotations

import http.client
import json
import logging
import ssl
import threading
import urllib.error
import urllib.request
from collections.abc import Mapping
from typing import Any

from td2adaptor.dashboard.fleet import Fleet
from td2adaptor.dashboard.tdforms import form_topic
from td2adaptor.runtime.bus.security import redact_url

log = logging.getLogger("td2adaptor.dashboard")

PERIOD = 10.0
TIMEOUT = 30.0


def robot_of(td: Mapping[str, Any], root: str) -> str | None:
    """The robot a TD is of: the level after `root` in the topics its forms name (the first form that has one)."""
    for kind in ("properties", "actions", "events"):
        group = td.get(kind)
        if not isinstance(group, Mapping):
            continue
        for affordance in group.values():
            forms = affordance.get("forms") if isinstance(affordance, Mapping) else None
            for form in forms if isinstance(forms, list) else [forms] if isinstance(forms, Mapping) else []:
                topic = form_topic(form) if isinstance(form, Mapping) else None
                levels = topic.split("/") if topic else []
                if len(levels) > 2 and levels[0] == root and levels[1] not in ("+", "#"):
                    return levels[1]
    return None


class DirectoryReader:
    """Reads the directory's listing into `fleet` on a thread of its own until `stop`."""

    def __init__(
        self, url: str, fleet: Fleet, *, token: str | None = None, ca_file: str | None = None, period: float = PERIOD
    ) -> None:
        self.url = url.rstrip("/")
        self.fleet = fleet
        self.token = token
        self.ca_file = ca_file
        self.period = period
        self.reads = 0  # listings read, for tests and logs
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="dashboard-directory", daemon=True)

    def __repr__(self) -> str:  # the token stays out of logs
        return f"DirectoryReader({redact_url(self.url)!r})"

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(TIMEOUT + 1)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                listing = self.read()
            except (OSError, ValueError, http.client.HTTPException) as exc:
                log.warning("the TD directory %s: %s", redact_url(self.url), exc)
            else:
                found = {robot: td for td in listing if (robot := robot_of(td, self.fleet.root)) is not None}
                self.fleet.directory_tds(found)
                self.reads += 1
            self._stop.wait(self.period)

    def read(self) -> list[dict[str, Any]]:
        """`GET /things`: the TDs it lists (a directory that pages its listing gives its first page)."""
        headers = {"Accept": "application/json"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        target = f"{self.url}/things"
        context = ssl.create_default_context(cafile=self.ca_file) if target.startswith("https:") else None
        request = urllib.request.Request(target, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=TIMEOUT, context=context) as answer:
                data = json.loads(answer.read())
        except urllib.error.HTTPError as exc:
            exc.close()
            raise ValueError(f"GET /things answered HTTP {exc.code} {exc.reason}") from None
        except urllib.error.URLError as exc:
            raise ValueError(f"GET /things: no answer ({exc.reason})") from None
        if not isinstance(data, list):
            raise ValueError("GET /things did not answer a list of Thing Descriptions")
        return [td for td in data if isinstance(td, dict)]
