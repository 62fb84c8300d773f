"""Parsing, validating and building event messages, with the schemas of `events_catalog`."""

from __future__ import annotations

import itertools
import json
import os
import re
import sys
import threading
import time
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]
from referencing import Registry, Resource
from referencing.jsonschema import DRAFT202012

from td2adaptor.model.events import EventCatalog, EventSpec, Kind

MAX_ERRORS = 10
EXCERPT = 1024
#: the deepest nesting of objects and arrays an event may have (a ROS message is seldom ten deep): a deeper one
#: is refused before a schema validator, a digest or a robot call has to follow it down
MAX_DEPTH = 64
#: the largest magnitude a number in an event may have: a double's (`1e400` parses as infinity)
_DOUBLE_MAX = sys.float_info.max
#: UTF-16 surrogates: a JSON string can hold one alone (`"\\ud800"`), but no UTF-8 text can
_SURROGATE = re.compile(r"[\ud800-\udfff]")
#: pointers in refusals are cut to this length (a member name can be as long as the event)
_POINTER_MAX = 200


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


class _Ids:
    """Event ids: a random 64-bit prefix per process (drawn again in a forked child) and a counter, 32 hex
    digits as a UUID's. Unique without a system call per event (os.urandom releases the GIL, and a busy edge
    node's threads then queue up to take it back)."""

    def __init__(self) -> None:
        self.reseed()

    def reseed(self) -> None:
        self.prefix = os.urandom(8).hex()
        self.counter = itertools.count(1)  # next() on it is atomic: no lock needed between threads


_ids = _Ids()
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_ids.reseed)


def new_id() -> str:
    return f"{_ids.prefix}{next(_ids.counter):016x}"


def loads(raw: bytes) -> Any:
    """JSON in UTF-8. `NaN` and `Infinity` are read (as is `1e400`, which is infinity to a double) so that
    `value_problem` can name where such a number is: no event that holds one is ever run or answered with it."""
    return json.loads(raw.decode("utf-8"))


def encode(event: Mapping[str, Any]) -> bytes:
    return json.dumps(event, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def excerpt(raw: bytes) -> str:
    return raw[:EXCERPT].decode("utf-8", errors="replace")[:EXCERPT]


def pointer(path: Any) -> str:
    text = "".join("/" + str(p).replace("~", "~0").replace("/", "~1") for p in path)
    if _SURROGATE.search(text):  # a member name that is no text: shown escaped, so the refusal can be sent
        text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    return text if len(text) <= _POINTER_MAX else text[: _POINTER_MAX - 3] + "..."


def is_text(value: str) -> bool:
    """Whether `value` can be encoded as UTF-8 (holds no lone surrogate), so that it can be sent again."""
    return value.isascii() or _SURROGATE.search(value) is None


def value_problem(data: Any) -> tuple[str, str] | None:
    """(JSON pointer, message) of the first thing in `data` that no event may hold, wherever it is: a number
    that is not finite or beyond a double (NaN, Infinity, `1e400`: no ROS number holds it), a string or member
    name that is not Unicode text (a lone surrogate: it cannot be encoded, so neither run nor echoed), nesting
    deeper than MAX_DEPTH. None when there is none. The schemas then check each number against its ROS type."""
    found = _problem(data, 0)
    if found is None:
        return None
    path, message = found
    return pointer(reversed(path)), message


def _problem(value: Any, depth: int) -> tuple[list[Any], str] | None:
    """`value_problem` with the path in reverse (built only on the way back from a problem)."""
    if isinstance(value, str):
        return None if is_text(value) else ([], _not_text(value))
    if isinstance(value, (int, float)):
        if -_DOUBLE_MAX <= value <= _DOUBLE_MAX:
            return None
        if value != value:  # NaN
            return [], "NaN: JSON has no such number"
        return [], f"number out of range: numbers must be finite, at most {_DOUBLE_MAX!r} in magnitude"
    if isinstance(value, (dict, list)):
        if depth >= MAX_DEPTH:
            return [], f"nested more than {MAX_DEPTH} levels deep"
        items = value.items() if isinstance(value, dict) else enumerate(value)
        for key, item in items:
            if isinstance(key, str) and not is_text(key):
                found: tuple[list[Any], str] | None = ([], "the member name is " + _not_text(key))
            else:
                found = _problem(item, depth + 1)
            if found is not None:
                found[0].append(key)
                return found
    return None


def _not_text(value: str) -> str:
    """Why a string with a lone surrogate is refused, the surrogate shown as its escape."""
    match = _SURROGATE.search(value)
    code = ord(match.group()) if match else 0
    return f"not Unicode text: it holds a lone surrogate (\\u{code:04x}), which UTF-8 cannot encode"


#: the validator of each catalog, by the catalog's identity, while an engine holds it (`validator_for`)
_VALIDATORS: weakref.WeakValueDictionary[int, EventValidator] = weakref.WeakValueDictionary()
_VALIDATORS_LOCK = threading.Lock()


def validator_for(catalog: EventCatalog) -> EventValidator:
    """The one `EventValidator` of `catalog` (nothing changes either once built): the robots of a fleet share
    one instead of compiling their own, which was half of what starting a robot cost the process (20 ms of
    CPU per RB-1 at idle, several times that under load)."""
    with _VALIDATORS_LOCK:
        found = _VALIDATORS.get(id(catalog))
        if found is not None and found.catalog is catalog:
            return found
    made = EventValidator(catalog)  # outside the lock: robots of other catalogs start meanwhile
    with _VALIDATORS_LOCK:
        found = _VALIDATORS.get(id(catalog))
        if found is not None and found.catalog is catalog:
            return found
        _VALIDATORS[id(catalog)] = made
        return made


class EventValidator:
    """Compiled validators for every event of a catalog (the envelope resolved through a local registry).

    Each event's own schema is validated directly, with its references to envelope members replaced by what
    they point to: jsonschema resolves a `$ref` again at every validation, which made an inbound event cost
    twice the time (the references themselves stay in the published schemas)."""

    def __init__(self, catalog: EventCatalog) -> None:
        self.catalog = catalog  # kept alive with it: `validator_for` keys on its identity
        resources = [(uri, Resource.from_contents(dict(schema), DRAFT202012)) for uri, schema in catalog.resources()]
        self.registry: Registry[Any] = Registry().with_resources(resources)
        self._validators = {
            spec.key: Draft202012Validator(self._inlined(catalog, spec), registry=self.registry)
            for spec in catalog.specs
        }

    def _inlined(self, catalog: EventCatalog, spec: EventSpec) -> Any:
        """`spec`'s schema with each property that is only a `$ref` (to a schema without references of its
        own) replaced by its target; the schema by reference where it is not an object schema."""
        schema = spec.schema
        props = schema.get("properties") if isinstance(schema, Mapping) else None
        if not isinstance(props, Mapping):
            return {"$ref": catalog.uri(spec)}
        resolver = self.registry.resolver(base_uri=catalog.uri(spec))
        inlined: dict[str, Any] = {}
        for name, sub in props.items():
            ref = sub.get("$ref") if isinstance(sub, Mapping) and len(sub) == 1 else None
            target = resolver.lookup(ref).contents if isinstance(ref, str) else None
            plain = isinstance(target, Mapping) and "$ref" not in json.dumps(target)
            inlined[name] = target if plain else sub
        return {**schema, "properties": inlined}

    def errors(self, spec: EventSpec, event: Any) -> list[tuple[str, str]]:
        """Up to MAX_ERRORS (instance pointer, message) pairs; empty when `event` is valid."""
        out: list[tuple[str, str]] = []
        for error in self._validators[spec.key].iter_errors(event):
            message = error.message if len(error.message) <= 300 else error.message[:297] + "..."
            path = pointer(error.absolute_path)
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
        except RecursionError:  # deeper than the parser follows: far beyond MAX_DEPTH
            return None, Problem(
                "invalid-event", f"not a valid {spec.key} event: nested more than {MAX_DEPTH} levels deep"
            )
        except (UnicodeDecodeError, ValueError) as exc:
            if "integer string conversion" in str(exc):  # an integer of thousands of digits
                message = f"not a valid {spec.key} event: a number out of range (thousands of digits)"
                return None, Problem("invalid-event", message)
            return None, Problem("invalid-json", f"not a JSON document: {str(exc)[:200]}")
        found = value_problem(event)
        if found is not None:
            return None, Problem(
                "invalid-event", f"not a valid {spec.key} event ({found[0] or '/'}: {found[1]})", (found,)
            )
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
    ok_corr = corr if isinstance(corr, str) and 0 < len(corr) <= 256 and is_text(corr) else None
    ok_mission = mission if isinstance(mission, int) and not isinstance(mission, bool) else None
    if ok_mission is not None and not -(2**63) <= ok_mission < 2**64:
        ok_mission = None
    return ok_corr, ok_mission
