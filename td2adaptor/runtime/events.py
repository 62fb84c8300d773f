"""Parsing, validating and building event messages, with the schemas of `events_catalog`."""

from __future__ import annotations

import json
import time
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

from td2adaptor.model.events import EventCatalog, EventSpec, Kind

MAX_ERRORS = 10
EXCERPT = 1024


@dataclass(frozen=True)
class Problem:
    """Why an inbound event was refused: an error-event code, a message and schema violations."""

    code: str
    message: str
    errors: tuple[tuple[str, str], ...] = ()


def now_rfc3339() -> str:
    """UTC time with milliseconds, e.g. 2026-01-31T12:00:00.123Z."""
    t = time.time()
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(t)) + f".{int(t % 1 * 1000):03d}Z"


def new_id() -> str:
    return uuid.uuid4().hex


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not JSON")


def loads(raw: bytes) -> Any:
    """Strict JSON: UTF-8, no NaN/Infinity (they would not survive the trip to another JSON parser)."""
    return json.loads(raw.decode("utf-8"), parse_constant=_no_constant)


def encode(event: Mapping[str, Any]) -> bytes:
    return json.dumps(event, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def excerpt(raw: bytes) -> str:
    return raw[:EXCERPT].decode("utf-8", errors="replace")[:EXCERPT]


def _pointer(path: Any) -> str:
    return "".join("/" + str(p).replace("~", "~0").replace("/", "~1") for p in path)


class EventValidator:
    """Compiled validators for every event of a catalog (the envelope resolved through a local registry)."""

    def __init__(self, catalog: EventCatalog) -> None:
        resources = [(uri, Resource.from_contents(dict(schema), DRAFT202012)) for uri, schema in catalog.resources()]
        self.registry: Registry[Any] = Registry().with_resources(resources)
        self._validators = {
            spec.key: Draft202012Validator({"$ref": catalog.uri(spec)}, registry=self.registry)
            for spec in catalog.specs
        }

    def errors(self, spec: EventSpec, event: Any) -> list[tuple[str, str]]:
        """Up to MAX_ERRORS (instance pointer, message) pairs; empty when `event` is valid."""
        out: list[tuple[str, str]] = []
        for error in self._validators[spec.key].iter_errors(event):
            message = error.message if len(error.message) <= 300 else error.message[:297] + "..."
            path = _pointer(error.absolute_path)
            if error.validator is None and not path and isinstance(event, dict):
                # jsonschema reports a `false` property schema without its name: say which member it is
                banned = [k for k, s in spec.schema["properties"].items() if s is False and k in event]
                if banned:
                    path, message = f"/{banned[0]}", f"{banned[0]!r} is not allowed in a {spec.kind.value} event"
            out.append((path, message))
            if len(out) >= MAX_ERRORS:
                break
        return sorted(out)

    def parse(self, spec: EventSpec, robot: str, raw: bytes) -> tuple[dict[str, Any] | None, Problem | None]:
        """The inbound event in `raw` (arrived on `spec`'s topic for `robot`), or why it is refused."""
        try:
            event = loads(raw)
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            return None, Problem("invalid-json", f"not a JSON document: {str(exc)[:200]}")
        errors = self.errors(spec, event)
        if errors:
            first = f"{errors[0][0] or '/'}: {errors[0][1]}"
            return None, Problem("invalid-event", f"not a valid {spec.key} event ({first})", tuple(errors))
        assert isinstance(event, dict)  # the schema says object
        if event.get("robot", robot) != robot:
            return None, Problem(
                "invalid-event", f"the event names robot {event['robot']!r} but arrived on the topic of {robot!r}"
            )
        return event, None


def envelope(
    kind: Kind,
    *,
    robot: str,
    source: str,
    payload: Any,
    affordance: str | None = None,
    correlation: str | None = None,
    mission: int | None = None,
) -> dict[str, Any]:
    """An outbound event with every envelope field the schemas require."""
    event: dict[str, Any] = {"type": kind.value}
    if affordance is not None:
        event["affordance"] = affordance
    event.update(robot=robot, id=new_id(), time=now_rfc3339(), source=source)
    if correlation is not None:
        event["correlation"] = correlation
    if mission is not None:
        event["mission"] = mission
    event["payload"] = payload
    return event


def salvage(raw: bytes) -> tuple[str | None, int | None]:
    """Correlation and mission of an event that failed validation, when they can still be read."""
    try:
        data = loads(raw)
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None, None
    return references(data)


def references(data: Any) -> tuple[str | None, int | None]:
    """Correlation and mission of a parsed event, each where it is of the kind the envelope allows."""
    if not isinstance(data, dict):
        return None, None
    corr = data.get("correlation")
    mission = data.get("mission")
    ok_corr = corr if isinstance(corr, str) and 0 < len(corr) <= 256 else None
    ok_mission = mission if isinstance(mission, int) and not isinstance(mission, bool) else None
    if ok_mission is not None and not -(2**63) <= ok_mission < 2**64:
        ok_mission = None
    return ok_corr, ok_mission
