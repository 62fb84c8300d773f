"""Robots from a W3C WoT Thing Description Directory as well as from the bus (`dashboard --directory URL`): the
directory's listing (`GET <directory>/things`) read every `period` seconds, each TD's robot told by the topics
its forms name (`<root>/<robot>/...`). A robot's retained TD on the bus wins over its directory copy (the
directory gives back JSON-LD re-framed from RDF, and may keep a TD until its ttl after the robot is gone); a
robot listed only there shows with the status the bus says, or none. The token (`TD2ADAPTOR_DIRECTORY_TOKEN`)
and CA file (`TD2ADAPTOR_DIRECTORY_CA_FILE`) are the edge node's; failures are logged (the URL redacted) and
retried at the next period, never in the dashboard's way.

A directory may page its listing (TD Discovery: a `Link` header with `rel="next"`): the reader asks for pages of
`PAGE` TDs and follows the next links, on the directory's own origin only (the token goes nowhere else), at
most `MAX_PAGES` of them; a directory that does not page answers everything at once."""

from __future__ import annotations

import http.client
import json
import logging
import ssl
import threading
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Mapping
from typing import Any

from td2adaptor.dashboard.fleet import Fleet
from td2adaptor.dashboard.tdforms import form_topic
from td2adaptor.runtime.bus.security import redact_url

log = logging.getLogger("td2adaptor.dashboard")

PERIOD = 10.0
TIMEOUT = 30.0
PAGE = 100  # TDs asked for per page of the listing
MAX_PAGES = 1000  # pages followed at most in one read (a directory whose next links loop ends here)


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
        self,
        url: str,
        fleet: Fleet,
        *,
        token: str | None = None,
        ca_file: str | None = None,
        period: float = PERIOD,
        page: int = PAGE,
    ) -> None:
        self.url = url.rstrip("/")
        self.page = page
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
        """`GET /things`, page after page: the TDs the directory lists."""
        target: str | None = f"{self.url}/things?limit={self.page}"
        tds: list[dict[str, Any]] = []
        pages = 0
        while target is not None and pages < MAX_PAGES:
            listing, target = self._page(target)
            tds += listing
            pages += 1
        return tds

    def _page(self, target: str) -> tuple[list[dict[str, Any]], str | None]:
        """One page of the listing and the next page's URL (None: the last page)."""
        headers = {"Accept": "application/json"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        context = ssl.create_default_context(cafile=self.ca_file) if target.startswith("https:") else None
        request = urllib.request.Request(target, headers=headers)
        try:
            with urllib.request.urlopen(request, timeout=TIMEOUT, context=context) as answer:
                data = json.loads(answer.read())
                link = answer.headers.get("Link")
        except urllib.error.HTTPError as exc:
            exc.close()
            raise ValueError(f"GET /things answered HTTP {exc.code} {exc.reason}") from None
        except urllib.error.URLError as exc:
            raise ValueError(f"GET /things: no answer ({exc.reason})") from None
        if not isinstance(data, list):
            raise ValueError("GET /things did not answer a list of Thing Descriptions")
        return [td for td in data if isinstance(td, dict)], self._next(target, link)

    def _next(self, target: str, link: str | None) -> str | None:
        """The `rel="next"` URL of a `Link` header, resolved against `target`; None when there is none or it
        leads off the directory's origin."""
        for value in urllib.request.parse_http_list(link or ""):
            reference, _, params = value.partition(";")
            reference = reference.strip()
            if not (reference.startswith("<") and reference.endswith(">")):
                continue
            rels = urllib.request.parse_keqv_list([p.strip() for p in params.split(";") if "=" in p]).get("rel", "")
            if "next" not in rels.split():
                continue
            url = urllib.parse.urljoin(target, reference[1:-1])
            here, there = urllib.parse.urlsplit(self.url), urllib.parse.urlsplit(url)
            if (here.scheme, here.netloc) != (there.scheme, there.netloc):
                log.warning("the TD directory %s: a next page on another origin is not followed", redact_url(self.url))
                return None
            return url
        return None
