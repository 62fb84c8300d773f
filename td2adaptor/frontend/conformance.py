"""TD 1.1 and Thing Model conformance: our JSON Schemas plus the checks a schema cannot express.

The schemas (`schemas/td-1.1.schema.json`, `schemas/tm-1.1.schema.json`) are td2adaptor's own, written from
the TD 1.1 Recommendation. Every violation is reported (not just the first) at the JSON pointer of the
offending value, with a one-line message; `oneOf`/`anyOf` failures are narrowed to the most plausible branch.
The extra checks mirror the Thingweb Playground's "additional" stage (security names, `rel: type` count,
enum+const, object/array without properties/items, readOnly+writeOnly, multi-language consistency, apikey in
URI) and the TM `tm:optional` resolver.

jsonschema is imported lazily and validators are compiled once per process: CLI start-up time matters.
"""

from __future__ import annotations

import calendar
import difflib
import json
import re
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from functools import cache
from typing import TYPE_CHECKING, Any

from td2adaptor.diagnostics import Diagnostics, Severity, pointer_join, pointer_tokens
from td2adaptor.diagnostics.catalogue import meanings
from td2adaptor.frontend.bundled import load_schema
from td2adaptor.frontend.jsonsrc import JsonDocument

if TYPE_CHECKING:
    from jsonschema.exceptions import ValidationError  # type: ignore[import-untyped, unused-ignore]
    from jsonschema.protocols import Validator  # type: ignore[import-untyped, unused-ignore]

TD_SCHEMA = "td-1.1.schema.json"
TM_SCHEMA = "tm-1.1.schema.json"

CODES: dict[str, str] = meanings("TD1")  # the codes this module reports (see the catalogue)

_WEAK = frozenset({"anyOf", "oneOf"})
_SIZE = frozenset({"minItems", "maxItems", "minProperties", "maxProperties", "uniqueItems", "minLength", "contains"})


# ---------------------------------------------------------------------------------------------------------
# formats


_DATE_TIME = re.compile(
    r"^(\d{4})-(\d{2})-(\d{2})[Tt](\d{2}):(\d{2}):(\d{2})(?:\.\d+)?(?:[Zz]|[+-](\d{2}):(\d{2}))\Z", re.ASCII
)


def is_date_time(value: object) -> bool:
    """RFC 3339 `date-time` (jsonschema only checks it when an optional package is installed)."""
    if not isinstance(value, str):
        return True
    m = _DATE_TIME.match(value)
    if m is None:
        return False
    year, month, day, hour, minute, second = (int(g) for g in m.groups()[:6])
    if not (1 <= month <= 12 and 1 <= day <= calendar.monthrange(year, month)[1]):
        return False
    if hour > 23 or minute > 59 or second > 60:
        return False
    off_h, off_m = m.group(7), m.group(8)
    return off_h is None or (int(off_h) <= 23 and int(off_m) <= 59)


_TEMPLATE_EXPR = re.compile(r"\{([^{}]*)\}")
_VARSPEC = re.compile(
    r"^(?:[A-Za-z0-9_]|%[0-9A-Fa-f]{2})(?:\.?(?:[A-Za-z0-9_]|%[0-9A-Fa-f]{2}))*(?::[1-9][0-9]{0,3}|\*)?\Z"
)
_BAD_LITERAL = re.compile(r"[\x00-\x20\"<>\\^`|{}\x7f]|%(?![0-9A-Fa-f]{2})")


def template_variables(href: str) -> list[str]:
    """Variable names used in the RFC 6570 expressions of `href` (operators and modifiers dropped)."""
    names: list[str] = []
    for expr in _TEMPLATE_EXPR.findall(href):
        body = expr[1:] if expr[:1] in "+#./;?&" else expr
        for spec in body.split(","):
            names.append(re.sub(r"(:\d+|\*)$", "", spec))
    return names


def is_uri_template(value: object) -> bool:
    """An IRI reference that may contain RFC 6570 expressions (TD form targets)."""
    if not isinstance(value, str):
        return True
    if "{" not in value and "}" not in value:
        return is_iri_reference(value)
    for expr in _TEMPLATE_EXPR.findall(value):
        body = expr[1:] if expr[:1] in "+#./;?&" else expr
        if not body or not all(_VARSPEC.match(spec) for spec in body.split(",")):
            return False
    return _BAD_LITERAL.search(_TEMPLATE_EXPR.sub("", value)) is None


# Parts of RFC 3986's grammar without percent-escapes, IP literals or a ':' in user info: unreserved and
# sub-delims characters (`_SAFE`), and those plus ':' and '@' (`_PCHAR`).
_SAFE = r"A-Za-z0-9\-._~!$&'()*+,;="
_PCHAR = _SAFE + ":@"
_REST = rf"(?:\?[{_PCHAR}/?]*)?(?:#[{_PCHAR}/?]*)?\Z"  # query and fragment
_AUTHORITY = rf"//(?:[{_SAFE}]*@)?[{_SAFE}]*(?::[0-9]*)?(?:/[{_PCHAR}/]*)?"  # with its path-abempty
_PLAIN_URI = rf"[A-Za-z][A-Za-z0-9+.\-]*:(?:{_AUTHORITY}|(?!//)[{_PCHAR}/]*){_REST}"
_PLAIN_RELATIVE = rf"(?:{_AUTHORITY}|/(?!/)[{_PCHAR}/]*|[{_SAFE}@]+(?:/[{_PCHAR}/]*)?|){_REST}"
_PLAIN = {"URI": _PLAIN_URI, "URI_reference": f"(?:{_PLAIN_URI})|(?:{_PLAIN_RELATIVE})"}


@cache
def _plain(rule: str) -> re.Pattern[str] | None:
    """A small regex that accepts only strings rfc3987's `rule` accepts, and the usual ones (`ros:svc/a`,
    `urn:dev:ops:1`, `https://host/path`): those are answered without rfc3987, whose URI regexes take ~10 ms
    of a CLI run to import and compile. tests/frontend/test_uri_plain.py checks the subset claim."""
    pattern = _PLAIN.get(rule)
    return None if pattern is None else re.compile(pattern)


def _rfc3987(rule: str) -> Callable[[object], bool]:
    """An RFC 3987 check. For ASCII text the IRI and URI grammars coincide (IRIs only add non-ASCII
    characters), and rfc3987's URI regexes compile ten times faster than its IRI ones (~40 ms per process)."""
    ascii_rule = rule.replace("IRI", "URI")

    def check(value: object) -> bool:
        if not isinstance(value, str):
            return True
        if value.isascii():
            plain = _plain(ascii_rule)
            if plain is not None and plain.match(value):
                return True
        import rfc3987

        return rfc3987.match(value, rule=ascii_rule if value.isascii() else rule) is not None

    return check


is_iri_reference = _rfc3987("IRI_reference")

_FORMAT_HINTS = {
    "date-time": "use an RFC 3339 timestamp such as 2019-03-14T09:13:37Z",
    "iri-reference": 'use an IRI (RFC 3987): no spaces or characters such as < > " { } | \\ ^ `',
    "uri": "use an absolute URI such as urn:dev:ops:my-thing-1234 or https://example.com/things/1",
    "uri-template": "use an IRI, optionally with RFC 6570 template expressions such as {?lat,long}",
}


@cache
def _format_checker() -> Any:
    """A FormatChecker that really checks the formats our schemas use (no silently skipped ones)."""
    from jsonschema import FormatChecker  # type: ignore[import-untyped, unused-ignore]

    checker = FormatChecker()
    checker.checks("date-time")(is_date_time)
    checker.checks("uri-template")(is_uri_template)
    checker.checks("iri-reference")(is_iri_reference)
    checker.checks("uri")(_rfc3987("URI"))
    checker.checks("iri")(_rfc3987("IRI"))
    return checker


@cache
def _fast_validator(schema_file: str) -> Any:
    """jsonschema-rs for the common case, a document without schema errors: it answers a 10,000-affordance TD
    in ~50 ms where jsonschema takes ~2 s, and spares a cold CLI jsonschema's import. Its verdict only decides
    whether jsonschema must look (tests/frontend/test_fast_schema.py keeps the two in agreement on every
    corpus document); the diagnostics always come from jsonschema. None when it is not installed."""
    try:
        import jsonschema_rs
    except ImportError:
        return None
    formats = {
        "date-time": is_date_time,
        "uri-template": is_uri_template,
        "iri-reference": is_iri_reference,
        "uri": _rfc3987("URI"),
        "iri": _rfc3987("IRI"),
    }
    return jsonschema_rs.validator_for(load_schema(schema_file), formats=formats, validate_formats=True)


def schema_valid(data: Any, schema_file: str) -> bool | None:
    """The fast validator's verdict on `data`; None when it cannot say (not installed, or data it refuses)."""
    fast = _fast_validator(schema_file)
    if fast is None:
        return None
    try:
        return bool(fast.is_valid(data))
    except (ValueError, TypeError, OverflowError):  # e.g. an integer beyond 64 bits
        return None


@cache
def validator(schema_file: str) -> Validator:
    """The compiled validator for one of our bundled schemas (built on first use, then reused)."""
    from jsonschema import Draft202012Validator  # type: ignore[import-untyped, unused-ignore]

    schema = load_schema(schema_file)
    return Draft202012Validator(schema, format_checker=_format_checker())


# ---------------------------------------------------------------------------------------------------------
# schema errors → diagnostics


@dataclass(frozen=True)
class _Finding:
    severity: Severity
    code: str
    message: str
    pointer: str
    hint: str | None = None


def _short(value: Any, limit: int = 60) -> str:
    """A compact JSON rendering of `value`, cut to `limit` characters."""
    text = json.dumps(value, ensure_ascii=False, separators=(", ", ": "))
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _jtype(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, (int, float)):
        return "number"
    return {dict: "object", list: "array", str: "string", type(None): "null"}.get(type(value), "value")


def _refine(err: ValidationError) -> tuple[ValidationError, bool]:
    """Narrow an anyOf/oneOf failure to the branch that most plausibly was meant.

    Like jsonschema's best_match, prefer the deepest error in a branch whose type fits the instance; unlike
    it, a tie goes to the first branch, a TM placeholder alternative is never the one described (the TD value
    is what the author most likely meant), and the descent is one level at a time so that a hand-written
    message on an inner alternative is kept. Also returns whether a placeholder would have been accepted.
    """
    from jsonschema.exceptions import relevance  # type: ignore[import-untyped, unused-ignore]

    placeholder_ok = False
    while err.validator in _WEAK and err.context and not _custom_message(err):
        branches = [e for e in err.context if not (isinstance(e.schema, dict) and e.schema.get("x-placeholder"))]
        placeholder_ok = placeholder_ok or len(branches) < len(err.context)
        err = min(branches or err.context, key=relevance)
    return err, placeholder_ok


def _custom_message(err: ValidationError) -> str | None:
    messages = err.schema.get("x-messages") if isinstance(err.schema, dict) else None
    if isinstance(messages, dict) and isinstance(messages.get(str(err.validator)), str):
        return str(messages[str(err.validator)]).format(instance=_short(err.instance))
    return None


def _did_you_mean(value: Any, choices: list[Any]) -> str | None:
    if not isinstance(value, str):
        return None
    strings = [c for c in choices if isinstance(c, str)]
    folded = {c.lower(): c for c in strings}
    if value.strip().lower() in folded:
        return f"did you mean {folded[value.strip().lower()]!r}?"
    close = difflib.get_close_matches(value, strings, n=1, cutoff=0.7)
    return f"did you mean {close[0]!r}?" if close else None


def _epoch_hint(value: Any) -> str | None:
    """`created: "1552554817"` is a Unix time: show the RFC 3339 form it should have been."""
    if isinstance(value, str) and re.fullmatch(r"\d{9,10}", value):
        import datetime

        stamp = datetime.datetime.fromtimestamp(int(value), tz=datetime.timezone.utc)
        return f"{value} looks like a Unix time; as RFC 3339 that is {stamp.strftime('%Y-%m-%dT%H:%M:%SZ')}"
    return None


def _describe(err: ValidationError) -> _Finding:
    """One readable line (plus hint) for a leaf schema error, located at the offending value."""
    pointer = pointer_join("", *err.absolute_path)
    inst, kw, val = err.instance, str(err.validator), err.validator_value
    schema = err.schema if isinstance(err.schema, dict) else {}
    hint = schema.get("x-hint") if isinstance(schema.get("x-hint"), str) else None
    code, message = "TD100", err.message
    custom = _custom_message(err)
    if kw == "required":
        missing = [name for name in val if isinstance(inst, dict) and name not in inst] or list(val)
        what = schema.get("title", "object")
        code, message = "TD101", f"{what} is missing required member {', '.join(map(repr, missing))}"
    elif kw == "type":
        expected = " or ".join(val) if isinstance(val, list) else str(val)
        code, message = "TD102", f"expected {expected}, found {_jtype(inst)} {_short(inst)}"
    elif kw in ("enum", "const"):
        choices = val if kw == "enum" else [val]
        code = "TD103"
        message = (
            f"{_short(inst)} is not one of {', '.join(_short(c) for c in choices)}"
            if kw == "enum"
            else f"{_short(inst)} is not allowed here, expected {_short(val)}"
        )
        if not (custom and hint):  # a hand-written message comes with its own advice
            hint = _did_you_mean(inst, choices) or hint
    elif kw == "format":
        code, message = "TD104", f"{_short(inst)} is not a valid {val}"
        hint = hint or (_epoch_hint(inst) if val == "date-time" else None) or _FORMAT_HINTS.get(str(val))
    elif kw == "pattern":
        code, message = "TD104", f"{_short(inst)} does not have the required form"
        hint = hint or f"it must match the regular expression {val}"
    elif kw in _SIZE:
        code = "TD105"
        if kw in ("minItems", "minProperties") and val == 1:
            message = f"{_short(inst)} must not be empty"
        elif kw == "uniqueItems" and isinstance(inst, list):
            dups = [v for v, n in Counter(_short(v) for v in inst).items() if n > 1]
            message = f"{_short(inst)} has duplicate items: {', '.join(dups)}"
        else:
            message = err.message
    elif kw == "not":
        code, message = "TD103", f"{_short(inst)} is not allowed here"
    elif kw in _WEAK:
        code, message = "TD100", f"{_short(inst)} matches none of the allowed forms"
        if err.context:
            branches = sorted({e.message for e in err.context})[:3]
            hint = hint or "; ".join(b if len(b) < 100 else b[:99] + "…" for b in branches)
    if custom is not None:
        code, message = ("TD103" if code == "TD100" else code), custom
    if list(err.absolute_path)[:1] == ["@context"] and kw in ("enum", "const", "not", "type", "minItems"):
        code = "TD106"
    if len(message) > 200:
        message = message[:199] + "…"
    return _Finding(Severity.ERROR, code, message, pointer, hint)


def _schema_findings(data: Any, schema_file: str) -> list[_Finding]:
    """All schema violations, narrowed, described and de-duplicated."""
    if schema_valid(data, schema_file):
        return []
    found: list[_Finding] = []
    seen: set[tuple[str, str]] = set()
    for err in validator(schema_file).iter_errors(data):
        leaf, placeholder_ok = _refine(err)
        finding = _describe(leaf)
        if placeholder_ok:
            advice = "a placeholder such as {{NAME}} is also accepted here"
            finding = replace(finding, hint=f"{finding.hint}; {advice}" if finding.hint else advice)
        if (finding.pointer, finding.message) not in seen:
            seen.add((finding.pointer, finding.message))
            found.append(finding)
    return found


# ---------------------------------------------------------------------------------------------------------
# walking a TD


_SCHEMA_CHILDREN = ("input", "output", "subscription", "data", "dataResponse", "cancellation")


def _affordances(data: dict[str, Any]) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """(kind, pointer, affordance) for every property, action and event."""
    for kind in ("properties", "actions", "events"):
        group = data.get(kind)
        if isinstance(group, dict):
            for name, aff in group.items():
                if isinstance(aff, dict):
                    yield kind, pointer_join("", kind, name), aff


def _forms(data: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any], str, dict[str, Any]]]:
    """(pointer, form, owner pointer, owner) for every form; the owner is an affordance or the Thing."""
    owners: list[tuple[str, dict[str, Any]]] = [("", data)]
    owners += [(ptr, aff) for _, ptr, aff in _affordances(data)]
    for owner_ptr, owner in owners:
        forms = owner.get("forms")
        if isinstance(forms, list):
            for i, form in enumerate(forms):
                if isinstance(form, dict):
                    yield pointer_join(owner_ptr, "forms", i), form, owner_ptr, owner


def iter_data_schemas(data: Any) -> Iterator[tuple[str, dict[str, Any]]]:
    """(pointer, schema) for every data schema of a TD/TM, nested ones included."""
    if not isinstance(data, dict):
        return
    roots: list[tuple[str, Any]] = []
    for key in ("schemaDefinitions", "uriVariables"):
        if isinstance(data.get(key), dict):
            roots += [(pointer_join("", key, n), s) for n, s in data[key].items()]
    for kind, ptr, aff in _affordances(data):
        if kind == "properties":
            roots.append((ptr, aff))
        roots += [(pointer_join(ptr, k), aff[k]) for k in _SCHEMA_CHILDREN if k in aff]
        if isinstance(aff.get("uriVariables"), dict):
            roots += [(pointer_join(ptr, "uriVariables", n), s) for n, s in aff["uriVariables"].items()]
    stack = list(reversed(roots))
    while stack:
        ptr, schema = stack.pop()
        if not isinstance(schema, dict):
            continue
        yield ptr, schema
        nested: list[tuple[str, Any]] = []
        if isinstance(schema.get("properties"), dict):
            nested += [(pointer_join(ptr, "properties", n), s) for n, s in schema["properties"].items()]
        items = schema.get("items")
        if isinstance(items, dict):
            nested.append((pointer_join(ptr, "items"), items))
        elif isinstance(items, list):
            nested += [(pointer_join(ptr, "items", i), s) for i, s in enumerate(items)]
        for key in ("oneOf", "allOf", "anyOf"):
            if isinstance(schema.get(key), list):
                nested += [(pointer_join(ptr, key, i), s) for i, s in enumerate(schema[key])]
        stack.extend(reversed(nested))


def _names(value: Any, ptr: str) -> list[tuple[str, str]]:
    """(name, pointer) of a `security` value: a string or an array of strings."""
    if isinstance(value, str):
        return [(value, ptr)]
    if isinstance(value, list):
        return [(v, pointer_join(ptr, i)) for i, v in enumerate(value) if isinstance(v, str)]
    return []


# ---------------------------------------------------------------------------------------------------------
# extra checks


def _check_security_names(data: dict[str, Any]) -> Iterator[_Finding]:
    defs = data.get("securityDefinitions")
    if not isinstance(defs, dict):
        return
    uses = _names(data.get("security"), "/security")
    for ptr, form, _, _ in _forms(data):
        uses += _names(form.get("security"), pointer_join(ptr, "security"))
    for name, ptr in uses:
        if name not in defs:
            yield _Finding(
                Severity.ERROR,
                "TD110",
                f"security scheme {name!r} is not defined in securityDefinitions",
                ptr,
                _did_you_mean(name, list(defs)) or f"define {name!r} in securityDefinitions",
            )
    for scheme_name, scheme in defs.items():
        if not isinstance(scheme, dict) or scheme.get("scheme") != "combo":
            continue
        for key in ("oneOf", "allOf"):
            for name, ptr in _names(scheme.get(key), pointer_join("/securityDefinitions", scheme_name, key)):
                if name == scheme_name:
                    yield _Finding(Severity.ERROR, "TD111", f"combo scheme {name!r} refers to itself", ptr)
                elif name not in defs:
                    yield _Finding(
                        Severity.ERROR,
                        "TD111",
                        f"combo scheme {scheme_name!r} refers to undefined scheme {name!r}",
                        ptr,
                        _did_you_mean(name, list(defs)),
                    )


def _check_additional_responses(data: dict[str, Any]) -> Iterator[_Finding]:
    defs = data.get("schemaDefinitions")
    names = list(defs) if isinstance(defs, dict) else []
    for ptr, form, _, _ in _forms(data):
        responses = form.get("additionalResponses")
        if not isinstance(responses, list):
            continue
        for i, resp in enumerate(responses):
            if isinstance(resp, dict) and isinstance(resp.get("schema"), str) and resp["schema"] not in names:
                yield _Finding(
                    Severity.ERROR,
                    "TD112",
                    f"additional response schema {resp['schema']!r} is not defined in schemaDefinitions",
                    pointer_join(ptr, "additionalResponses", i, "schema"),
                    _did_you_mean(resp["schema"], names)
                    or "name an entry of the Thing's schemaDefinitions (not an inline schema)",
                )


def _check_links(data: dict[str, Any]) -> Iterator[_Finding]:
    links = data.get("links")
    if not isinstance(links, list):
        return
    typed = [i for i, link in enumerate(links) if isinstance(link, dict) and link.get("rel") == "type"]
    for i in typed[1:]:
        yield _Finding(
            Severity.ERROR,
            "TD113",
            f"{len(typed)} links have rel 'type'; a Thing may link to at most one Thing Model",
            pointer_join("/links", i, "rel"),
            f"keep only one of the links {', '.join(f'/links/{j}' for j in typed)}",
        )


def _check_schemas(data: dict[str, Any]) -> Iterator[_Finding]:
    for ptr, schema in iter_data_schemas(data):
        if "enum" in schema and "const" in schema:
            yield _Finding(
                Severity.WARNING,
                "TD120",
                "data schema has both enum and const",
                ptr,
                "keep const for a single value, or enum for a choice",
            )
        composed = any(k in schema for k in ("oneOf", "allOf", "anyOf"))
        if schema.get("type") == "object" and "properties" not in schema and not composed:
            yield _Finding(
                Severity.WARNING,
                "TD121",
                "object schema without properties: its members are not described",
                ptr,
                "add 'properties' describing the members",
            )
        if schema.get("type") == "array" and "items" not in schema and not composed:
            yield _Finding(
                Severity.WARNING,
                "TD122",
                "array schema without items: its elements are not described",
                ptr,
                "add 'items' describing the elements",
            )
        if schema.get("readOnly") is True and schema.get("writeOnly") is True:
            yield _Finding(
                Severity.WARNING,
                "TD123",
                "readOnly and writeOnly are both true: the value can be neither read nor written",
                pointer_join(ptr, "writeOnly"),
            )
    props = data.get("properties")
    for name, prop in props.items() if isinstance(props, dict) else ():
        if not isinstance(prop, dict) or not isinstance(prop.get("forms"), list):
            continue
        ro, wo = prop.get("readOnly") is True, prop.get("writeOnly") is True
        for i, form in enumerate(prop["forms"]):
            ops = form.get("op") if isinstance(form, dict) else None
            for op, op_ptr in _names(ops, pointer_join("/properties", name, "forms", i, "op")):
                if (ro and op == "writeproperty") or (wo and op in ("readproperty", "observeproperty")):
                    flag = "readOnly" if ro else "writeOnly"
                    yield _Finding(
                        Severity.WARNING,
                        "TD124",
                        f"operation {op!r} contradicts {flag}: true of property {name!r}",
                        op_ptr,
                    )


@cache
def _language_tag() -> re.Pattern[str]:
    """The BCP 47 pattern, taken from our schema so there is a single definition."""
    return re.compile(load_schema(TD_SCHEMA)["$defs"]["languageTag"]["pattern"])


_NOT_STRUCTURE = frozenset({"@context", "const", "default", "enum", "examples"})


def _language_maps(value: Any, ptr: str) -> Iterator[tuple[str, dict[str, Any]]]:
    if isinstance(value, dict):
        for key, child in value.items():
            if key in _NOT_STRUCTURE:
                continue
            if key in ("titles", "descriptions") and isinstance(child, dict):
                yield pointer_join(ptr, key), child
            else:
                yield from _language_maps(child, pointer_join(ptr, key))
    elif isinstance(value, list):
        for i, child in enumerate(value):
            yield from _language_maps(child, pointer_join(ptr, i))


def _check_languages(data: dict[str, Any]) -> Iterator[_Finding]:
    maps = list(_language_maps(data, ""))
    tag = _language_tag()
    for ptr, lang_map in maps:
        for lang in lang_map:
            if not tag.match(lang):
                yield _Finding(
                    Severity.WARNING,
                    "TD126",
                    f"{lang!r} is not a well-formed BCP 47 language tag",
                    pointer_join(ptr, lang),
                    "use tags such as 'en', 'de-CH' or 'zh-Hant'",
                )
    sets = [frozenset(k.lower() for k in m) for _, m in maps]
    if len(set(sets)) <= 1:
        return
    common = Counter(sets).most_common(1)[0][0]
    for (ptr, _), langs in zip(maps, sets, strict=True):
        if langs != common:
            missing, extra = sorted(common - langs), sorted(langs - common)
            parts = ([f"lacks {', '.join(missing)}"] if missing else []) + (
                [f"adds {', '.join(extra)}"] if extra else []
            )
            yield _Finding(
                Severity.WARNING,
                "TD125",
                f"languages differ from the other multi-language maps ({'; '.join(parts)})",
                ptr,
                f"use the same languages in every titles/descriptions map: {', '.join(sorted(common))}",
            )


def _check_apikey_uri(data: dict[str, Any]) -> Iterator[_Finding]:
    defs = data.get("securityDefinitions")
    if not isinstance(defs, dict):
        return

    def uri_keys(name: str, seen: frozenset[str]) -> list[str]:
        scheme = defs.get(name)
        if not isinstance(scheme, dict) or name in seen:
            return []
        if scheme.get("scheme") == "apikey" and scheme.get("in") == "uri" and isinstance(scheme.get("name"), str):
            return [scheme["name"]]
        if scheme.get("scheme") == "combo" and isinstance(scheme.get("allOf"), list):
            return [k for n in scheme["allOf"] if isinstance(n, str) for k in uri_keys(n, seen | {name})]
        return []

    reported: set[str] = set()
    for ptr, form, owner_ptr, owner in _forms(data):
        names = _names(form.get("security", data.get("security")), "")
        keys = [k for n, _ in names for k in uri_keys(n, frozenset())]
        if not keys or not isinstance(form.get("href"), str):
            continue
        used = template_variables(form["href"])
        for key in keys:
            if key not in used:
                yield _Finding(
                    Severity.WARNING,
                    "TD127",
                    f"the apikey scheme puts its key into the URI, but href has no variable {{{key}}}",
                    pointer_join(ptr, "href"),
                    f"add {{{key}}} where the key goes, e.g. https://example.com/{{{key}}}/status",
                )
            for where, variables in {
                "": data.get("uriVariables"),
                owner_ptr: owner.get("uriVariables"),
            }.items():
                var_ptr = pointer_join(where, "uriVariables", key)
                if isinstance(variables, dict) and key in variables and var_ptr not in reported:
                    reported.add(var_ptr)
                    yield _Finding(
                        Severity.WARNING,
                        "TD128",
                        f"URI variable {key!r} is also the name of an apikey carried in the URI",
                        var_ptr,
                        "security key variables and uriVariables must be distinct; rename one of them",
                    )


def _check_tm_optional(data: dict[str, Any]) -> Iterator[_Finding]:
    optional = data.get("tm:optional")
    if not isinstance(optional, list):
        return
    for i, entry in enumerate(optional):
        if not isinstance(entry, str) or not re.fullmatch(r"/(properties|actions|events)/[^/]+", entry):
            continue  # the schema already reports malformed entries
        kind, name = pointer_tokens(entry)
        group = data.get(kind)
        if not isinstance(group, dict) or not isinstance(group.get(name), dict):
            names = list(group) if isinstance(group, dict) else []
            close = difflib.get_close_matches(name, names, n=1, cutoff=0.7)
            yield _Finding(
                Severity.ERROR,
                "TD114",
                f"tm:optional entry {entry!r} does not point to an existing affordance",
                pointer_join("/tm:optional", i),
                f"did you mean {pointer_join('', kind, close[0])!r}?"
                if close
                else f"the model has no {kind} entry {name!r}",
            )


# ---------------------------------------------------------------------------------------------------------
# entry points


def _emit(doc: JsonDocument, diags: Diagnostics, findings: list[_Finding]) -> None:
    """Report in document order (positions are only computed when there is something to report)."""
    if not findings:
        return
    order = {f.pointer: doc.offset(f.pointer) or 0 for f in findings} if doc.text else {}
    for f in sorted(findings, key=lambda f: order.get(f.pointer, 0)):
        diags.add(f.code, f.severity, f.message, f.pointer, f.hint)


def check_td(doc: JsonDocument, diags: Diagnostics) -> None:
    """Validate a Thing Description (TD 1.1, or 1.0): schema plus the Playground's additional checks."""
    findings = _schema_findings(doc.data, TD_SCHEMA)
    data = doc.data
    if isinstance(data, dict):
        for check in (
            _check_security_names,
            _check_additional_responses,
            _check_links,
            _check_schemas,
            _check_languages,
            _check_apikey_uri,
        ):
            findings.extend(check(data))
    _emit(doc, diags, findings)


def check_tm(doc: JsonDocument, diags: Diagnostics) -> None:
    """Validate a Thing Model: TM schema, tm:optional resolution and the advice checks that apply to models.

    Security cross-references are not checked: a model may inherit them through tm:extends.
    """
    findings = _schema_findings(doc.data, TM_SCHEMA)
    data = doc.data
    if isinstance(data, dict):
        for check in (_check_tm_optional, _check_links, _check_schemas, _check_languages):
            findings.extend(check(data))
    _emit(doc, diags, findings)
