"""A fast first check of inbound events: most events are valid, and proving it in Rust costs about 1 µs where
the Python validator (`events.EventValidator`) takes 20–100 µs on the engine's loop for every event.

`FastCheck.parse` answers an event that is valid without the Python validator: the JSON parsed, the values
every event must hold (`events.value_problem`), its schema checked by jsonschema-rs (the pinned Rust validator,
Draft 2020-12, formats not asserted as the Python one does not) and the robot it names. Anything else (an
invalid event, a schema the Rust validator cannot compile, an event whose schema uses a keyword the two
validators may judge differently) goes to `EventValidator.parse` as before, which decides and words the
refusal: the Rust check only ever lets through what it proves valid, and where it is the stricter of the two
(ECMA regular expressions: `\\d` and `\\w` are ASCII, `$` does not match before a final newline) the Python
validator still decides.

Keywords whose verdicts may differ are left to Python for the whole event: a `pattern` other than the
envelope's own (a TD's own pattern: ECMA's `\\s` takes characters Python's does not), `patternProperties`,
`multipleOf` (floating-point remainders), `uniqueItems` and `format`.
"""

from __future__ import annotations

import hashlib
import json
import threading
import weakref
from collections.abc import Iterator, Mapping
from typing import Any

import jsonschema_rs

from td2adaptor.model.events import EventCatalog, EventSpec
from td2adaptor.runtime.events import EventValidator, Problem, loads, value_problem

#: keywords whose verdict the Rust and the Python validators may give differently (see the module docstring)
_LEFT_TO_PYTHON = ("patternProperties", "multipleOf", "uniqueItems", "format")


class FastCheck:
    """`parse` as `EventValidator.parse`, the valid events proved so by jsonschema-rs (see the module
    docstring). Each event kind's Rust validator is compiled on its first event (a large TD's engine compiles
    only what it is sent), once for every engine of the process whose schemas are the same (a fleet's robots
    of one TD share them: a registry and validators per robot cost 0.6 MiB each)."""

    def __init__(self, catalog: EventCatalog, validator: EventValidator) -> None:
        self.validator = validator
        self._compiled = _compiled_for(catalog)
        self._checks = self._compiled.checks  # by spec key: a compiled validator, or None (left to Python)

    def parse(self, spec: EventSpec, robot: str, raw: bytes) -> tuple[dict[str, Any] | None, Problem | None]:
        """The inbound event in `raw`, or why it is refused (`EventValidator.parse`'s contract)."""
        check = self._checks.get(spec.key, False)
        if check is False:
            check = self._compiled.compile(spec)
        if check is not None:
            try:
                event = loads(raw)
                fast = isinstance(event, dict) and value_problem(event) is None and check.is_valid(event)
            except (UnicodeDecodeError, ValueError, RecursionError, OverflowError, TypeError):
                fast = False
            if fast and event.get("robot", robot) == robot:
                return event, None
        return self.validator.parse(spec, robot, raw)

    def compiled(self, spec: EventSpec) -> bool:
        """Whether `spec`'s valid events are proved so in Rust (False: the Python validator checks them all)."""
        check = self._checks.get(spec.key, False)
        return (self._compiled.compile(spec) if check is False else check) is not None


class _Compiled:
    """The Rust validators of one set of schema documents (shared by the engines that have the same)."""

    def __init__(self, catalog: EventCatalog) -> None:
        self.catalog = catalog
        self.checks: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._registry: Any = None
        self._patterns: frozenset[str] | None = None  # the envelope's own patterns

    def compile(self, spec: EventSpec) -> Any:
        """The Rust validator of `spec`'s events, or None where Python must decide (see the module docstring)."""
        with self._lock:
            if spec.key in self.checks:
                return self.checks[spec.key]
            check: Any = None
            try:
                if self._registry is None:
                    resources = [(uri, _plain(doc)) for uri, doc in self.catalog.resources()]
                    self._registry = jsonschema_rs.Registry(resources)
                    self._patterns = frozenset(_patterns(self.catalog.envelope))
                assert self._patterns is not None
                if comparable(spec.schema, self._patterns):
                    check = jsonschema_rs.Draft202012Validator(
                        {"$ref": self.catalog.uri(spec)}, registry=self._registry, validate_formats=False
                    )
            except Exception:  # noqa: BLE001 - a schema the Rust validator cannot take: Python validates it
                check = None
            self.checks[spec.key] = check
            return check


#: the compiled validators of each set of schema documents, by their digest, while an engine uses them
_COMPILED: weakref.WeakValueDictionary[str, _Compiled] = weakref.WeakValueDictionary()
_COMPILED_LOCK = threading.Lock()


def _compiled_for(catalog: EventCatalog) -> _Compiled:
    text = json.dumps(catalog.resources(), sort_keys=True, ensure_ascii=False)
    key = hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()
    with _COMPILED_LOCK:
        found = _COMPILED.get(key)
        if found is None:
            found = _COMPILED[key] = _Compiled(catalog)
        return found


def _plain(doc: Mapping[str, Any]) -> Any:
    """A schema document as plain dicts and lists (the catalog's may be read-only mappings)."""
    return json.loads(json.dumps(doc))


def _walk(schema: Any) -> Iterator[tuple[Any, Any]]:
    """Every (key, value) pair of every object in `schema`."""
    stack = [schema]
    while stack:
        node = stack.pop()
        if isinstance(node, Mapping):
            for key, value in node.items():
                yield key, value
                stack.append(value)
        elif isinstance(node, (list, tuple)):
            stack.extend(node)


def _patterns(schema: Any) -> list[str]:
    return [value for key, value in _walk(schema) if key == "pattern" and isinstance(value, str)]


def comparable(schema: Any, envelope_patterns: frozenset[str]) -> bool:
    """Whether both validators judge `schema`'s events alike wherever the Rust one accepts (see the module
    docstring): none of the keywords left to Python, and no pattern but the envelope's."""
    for key, value in _walk(schema):
        if key in _LEFT_TO_PYTHON:
            return False
        if key == "pattern" and not (isinstance(value, str) and value in envelope_patterns):
            return False
    return True
