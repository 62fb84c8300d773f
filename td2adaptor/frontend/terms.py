"""Unknown-term checking: the TD schema allows any extra member, so misspellings pass silently.

A TD is JSON-LD: a member that is not a TD 1.1 term at its position and not a compact IRI with a declared
prefix is dropped by every JSON-LD processor (or, with the TD context's `@vocab`, turned into a meaningless
`td:` IRI). So `titel`, `lastModified` or `ros:TopicName` without a `ros` prefix silently lose information.
This module walks the TD position by position (Thing, affordances, forms, data schemas, security schemes,
links, responses, version) and reports such members as warnings with a did-you-mean hint.

Member names chosen by the author (affordance names, uriVariables, securityDefinitions, schemaDefinitions,
data-schema `properties` names, language tags) are not terms; only a colon in a data-schema member name is
suspicious, because it reads as a compact IRI (e.g. `"level:"`).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from td2adaptor.diagnostics import Diagnostics, pointer_join
from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.frontend.bundled import load_schema
from td2adaptor.frontend.jsonsrc import JsonDocument
from td2adaptor.model.vocabulary import (
    ACTION,
    ADDITIONAL_RESPONSE,
    ALL_TERMS,
    ANY_SECURITY,
    DATA_SCHEMA,
    EVENT,
    EXPECTED_RESPONSE,
    FORM,
    JSON_SCHEMA_ONLY,
    LINK,
    PROPERTY,
    SECURITY,
    SECURITY_COMMON,
    THING,
    VERSION,
)

CODES: dict[str, str] = meanings("TD20")  # the codes this module reports (see the catalogue)

# prefixes the TD 1.1 context declares (the 2019 and 2022 context documents are identical)
TD_PREFIXES = frozenset({"td", "jsonschema", "wotsec", "hctl", "rdfs", "xsd", "dct", "htv", "tm"})

# bundled contexts other than the TD one, whose terms and prefixes are known without fetching them
_BUNDLED_CONTEXTS = {"https://td2adaptor.dev/ns/rosv/v1": "rosv-context-v1.jsonld"}

_TD_CONTEXTS = (
    "https://www.w3.org/2022/wot/td/v1.1",
    "https://www.w3.org/2019/wot/td/v1",
    "http://www.w3.org/ns/td",
)

_POSITIONS: tuple[tuple[str, frozenset[str]], ...] = (
    ("Thing", THING),
    ("property affordances", PROPERTY),
    ("action affordances", ACTION),
    ("event affordances", EVENT),
    ("data schemas", DATA_SCHEMA),
    ("forms", FORM),
    ("additional responses", ADDITIONAL_RESPONSE),
    ("links", LINK),
    ("version", VERSION),
    *((f"{name} security schemes", terms - SECURITY_COMMON) for name, terms in SECURITY.items()),
    ("security schemes", SECURITY_COMMON),
)


def _article(noun: str) -> str:
    return "an" if noun[:1].lower() in "aeiou" else "a"


# members every position tolerates: a JSON Schema comment, ignored by JSON-LD; embedded contexts
_ANYWHERE = frozenset({"$comment", "@context"})


@dataclass
class _Walk:
    """State of one walk: the declared names and what has been found so far."""

    declared: frozenset[str]
    remote: list[str]
    diags: Diagnostics
    undeclared: dict[str, list[Any]] = field(default_factory=dict)  # prefix -> [first pointer, count, key]

    # -- classification ------------------------------------------------------------------------------------
    def member(self, obj: dict[str, Any], ptr: str, key: str, allowed: frozenset[str], where: str) -> bool:
        """Check one member name; True when it is a TD term at this position (so its value is walked)."""
        if key in allowed:
            return True
        if key in _ANYWHERE or key in self.declared:
            return False
        prefix, colon, suffix = key.partition(":")
        if colon and prefix == BINDING_PREFIX and key not in binding_terms():
            close = difflib.get_close_matches(key, sorted(binding_terms()), n=1, cutoff=0.6)
            hint = f"did you mean {close[0]!r}?" if close else "the binding's terms: docs/binding.md"
            self.diags.warning(
                "TD201", f"unknown binding term {key!r} in {_article(where)} {where}", pointer_join(ptr, key), hint
            )
            return False
        if colon and prefix and suffix:
            if suffix.startswith("//") or prefix in self.declared:
                return False  # absolute IRI, or compact IRI with a declared prefix
            entry = self.undeclared.setdefault(prefix, [pointer_join(ptr, key), 0, key])
            entry[1] += 1
            return False
        message, hint = self._unknown_message(key, where), self._hint(obj, key, allowed, where)
        self.diags.warning("TD201", message, pointer_join(ptr, key), hint)
        return False

    @staticmethod
    def _unknown_message(key: str, where: str) -> str:
        place = f"the {where}" if where == "Thing" else f"{_article(where)} {where}"
        if key in ALL_TERMS:
            return f"{key!r} is a TD term, but not valid in {place}"
        return f"unknown term {key!r} in {place}"

    @staticmethod
    def _hint(obj: dict[str, Any], key: str, allowed: frozenset[str], where: str) -> str:
        bare = key.strip(": \t")
        folded = {t.lower(): t for t in allowed}
        if bare.lower() in folded and folded[bare.lower()] != key:
            return f"did you mean {folded[bare.lower()]!r}?"
        if key in ALL_TERMS:
            if key in DATA_SCHEMA and where == "event affordance":
                return "data schema terms of an event belong in its 'data' schema"
            if key in DATA_SCHEMA and where == "action affordance":
                return "data schema terms of an action belong in its 'input' or 'output' schema"
            homes = [name for name, terms in _POSITIONS if key in terms]
            return f"it is a term of: {', '.join(homes)}"
        if key in JSON_SCHEMA_ONLY:
            return f"{key!r} is a JSON Schema keyword that TD 1.1 data schemas lack; consumers ignore it"
        close = difflib.get_close_matches(key, sorted(allowed), n=1, cutoff=0.7)
        if close:
            return f"did you mean {close[0]!r}?"
        value = obj[key]
        if isinstance(value, dict) and "forms" in value:
            return "it looks like an interaction affordance: should it be under properties, actions or events?"
        if isinstance(value, dict) and "type" in value and "properties" in allowed:
            return "it looks like a data schema: should it be inside 'properties'?"
        return (
            "TD 1.1 does not define it here, so consumers ignore it; for an extension use a compact IRI "
            "(prefix:term) with the prefix declared in @context"
        )

    # -- positions -----------------------------------------------------------------------------------------
    def walk(
        self,
        obj: Any,
        ptr: str,
        allowed: frozenset[str],
        where: str,
        children: dict[str, Callable[[Any, str], None]],
    ) -> None:
        if not isinstance(obj, dict):
            return
        for key, value in obj.items():
            if self.member(obj, ptr, key, allowed, where) and key in children:
                children[key](value, pointer_join(ptr, key))

    def each(self, handler: Callable[[Any, str], None]) -> Callable[[Any, str], None]:
        """Apply `handler` to every element of an array (or to a lone object given where an array belongs)."""

        def run(value: Any, ptr: str) -> None:
            if isinstance(value, list):
                for i, item in enumerate(value):
                    handler(item, pointer_join(ptr, i))
            elif isinstance(value, dict):
                handler(value, ptr)

        return run

    def named(self, handler: Callable[[Any, str], None]) -> Callable[[Any, str], None]:
        """Apply `handler` to every value of a map whose keys are names chosen by the author."""

        def run(value: Any, ptr: str) -> None:
            if isinstance(value, dict):
                for name, item in value.items():
                    handler(item, pointer_join(ptr, name))

        return run

    def thing(self, obj: Any, ptr: str) -> None:
        ds = self.named(self.data_schema)
        self.walk(
            obj,
            ptr,
            THING,
            "Thing",
            {
                "properties": self.named(self.property),
                "actions": self.named(self.action),
                "events": self.named(self.event),
                "forms": self.each(self.form),
                "links": self.each(self.link),
                "securityDefinitions": self.named(self.security),
                "schemaDefinitions": ds,
                "uriVariables": ds,
                "version": self.version,
            },
        )

    def _schema_children(self) -> dict[str, Callable[[Any, str], None]]:
        schemas = self.each(self.data_schema)
        return {
            "properties": self.schema_members,
            "items": schemas,
            "oneOf": schemas,
            "allOf": schemas,
            "anyOf": schemas,
        }

    def _affordance_children(self) -> dict[str, Callable[[Any, str], None]]:
        return {"forms": self.each(self.form), "uriVariables": self.named(self.data_schema)}

    def property(self, obj: Any, ptr: str) -> None:
        self.walk(
            obj,
            ptr,
            PROPERTY,
            "property affordance",
            {**self._schema_children(), **self._affordance_children()},
        )

    def action(self, obj: Any, ptr: str) -> None:
        children = self._affordance_children()
        children.update(input=self.data_schema, output=self.data_schema)
        self.walk(obj, ptr, ACTION, "action affordance", children)

    def event(self, obj: Any, ptr: str) -> None:
        children = self._affordance_children()
        for key in ("subscription", "data", "dataResponse", "cancellation"):
            children[key] = self.data_schema
        self.walk(obj, ptr, EVENT, "event affordance", children)

    def data_schema(self, obj: Any, ptr: str) -> None:
        self.walk(obj, ptr, DATA_SCHEMA, "data schema", self._schema_children())

    def schema_members(self, value: Any, ptr: str) -> None:
        """The `properties` map of an object schema: names are data, but a colon in one is suspicious."""
        if not isinstance(value, dict):
            return
        for name, schema in value.items():
            prefix, colon, suffix = name.partition(":")
            if colon and not (prefix and suffix and (prefix in self.declared or suffix.startswith("//"))):
                bare = name.strip(":")
                hint = (
                    f"did you mean {bare!r}?"
                    if bare and ":" not in bare
                    else f"a colon reads as a compact IRI: rename it or declare prefix {prefix!r} in @context"
                )
                self.diags.warning(
                    "TD203",
                    f"suspicious property name {name!r}: it contains a colon",
                    pointer_join(ptr, name),
                    hint,
                )
            self.data_schema(schema, pointer_join(ptr, name))

    def form(self, obj: Any, ptr: str) -> None:
        self.walk(
            obj,
            ptr,
            FORM,
            "form",
            {
                "response": lambda v, p: self.walk(v, p, EXPECTED_RESPONSE, "expected response", {}),
                "additionalResponses": self.each(
                    lambda v, p: self.walk(v, p, ADDITIONAL_RESPONSE, "additional response", {})
                ),
            },
        )

    def link(self, obj: Any, ptr: str) -> None:
        self.walk(obj, ptr, LINK, "link", {})

    def version(self, obj: Any, ptr: str) -> None:
        self.walk(obj, ptr, VERSION, "version", {})

    def security(self, obj: Any, ptr: str) -> None:
        scheme = obj.get("scheme") if isinstance(obj, dict) else None
        allowed = SECURITY.get(scheme, ANY_SECURITY) if isinstance(scheme, str) else ANY_SECURITY
        where = f"{scheme} security scheme" if isinstance(scheme, str) and scheme in SECURITY else "security scheme"
        self.walk(obj, ptr, allowed, where, {})

    # -- undeclared prefixes -------------------------------------------------------------------------------
    def report_prefixes(self) -> None:
        for prefix, (ptr, count, key) in self.undeclared.items():
            uses = f"{count} uses, e.g. {key!r}" if count > 1 else f"in {key!r}"
            hint = f'declare it in @context, e.g. {{"{prefix}": "<namespace IRI>"}}'
            if self.remote:
                hint += f" (unless the remote context {self.remote[0]!r} declares it; it is not fetched)"
            self.diags.warning("TD202", f"prefix {prefix!r} is not declared in @context ({uses})", ptr, hint)


BINDING_PREFIX = "rosv"


@cache
def binding_terms() -> frozenset[str]:
    """Every term of the td2adaptor binding (`rosv:*`), as its bundled context defines them."""
    context = load_schema(_BUNDLED_CONTEXTS["https://td2adaptor.dev/ns/rosv/v1"]).get("@context", {})
    return frozenset(k for k in context if k.startswith(BINDING_PREFIX + ":"))


def _declared(context: Any) -> tuple[frozenset[str], list[str]]:
    """Names (prefixes and terms) a @context declares, and the remote contexts it names but we do not know."""
    names: set[str] = set(TD_PREFIXES)
    remote: list[str] = []
    entries = context if isinstance(context, list) else [context]
    for entry in entries:
        if isinstance(entry, dict):
            names.update(k for k in entry if not k.startswith("@"))
        elif isinstance(entry, str) and entry in _BUNDLED_CONTEXTS:
            bundled = load_schema(_BUNDLED_CONTEXTS[entry]).get("@context", {})
            names.update(k for k in bundled if not k.startswith("@"))
        elif isinstance(entry, str) and entry not in _TD_CONTEXTS:
            remote.append(entry)
    return frozenset(names), remote


def check_terms(doc: JsonDocument, diags: Diagnostics) -> None:
    """Warn about members that JSON-LD would drop: unknown terms (TD201), undeclared prefixes (TD202, once
    per prefix) and colons in data-schema member names (TD203)."""
    if not isinstance(doc.data, dict):
        return
    declared, remote = _declared(doc.data.get("@context"))
    walk = _Walk(declared, remote, diags)
    walk.thing(doc.data, "")
    walk.report_prefixes()
