"""Checking a TD against the Thing Model it links (`rel: type`): mandatory affordances and data types."""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

from td2adaptor.diagnostics import Diagnostics, Severity, pointer_join
from td2adaptor.frontend.jsonsrc import JsonDocument
from td2adaptor.frontend.thingmodel.common import (
    AFFORDANCE_KINDS,
    PLACEHOLDER,
    is_thing_model,
)
from td2adaptor.frontend.thingmodel.optional import optional_affordances
from td2adaptor.frontend.thingmodel.resolve import Resolver


def _data_type(kind: str, aff: Mapping[str, Any]) -> list[tuple[str, Any]]:
    """(member, type) pairs worth comparing between a model's affordance and a TD's."""
    if kind == "properties":
        return [("type", aff.get("type"))]
    if kind == "actions":
        return [(m, aff[m].get("type")) for m in ("input", "output") if isinstance(aff.get(m), dict)]
    return [("data", aff["data"].get("type"))] if isinstance(aff.get("data"), dict) else []


def _name_pattern(name: str) -> re.Pattern[str]:
    """Affordance names in a model may hold placeholders: match them against any text."""
    parts = PLACEHOLDER.split(name)
    return re.compile("".join(re.escape(p) if i % 2 == 0 else ".+" for i, p in enumerate(parts)) + r"\Z")


def check_against_model(td_doc: JsonDocument, diags: Diagnostics) -> None:
    """A TD that links its Thing Model (`rel: type`) must offer every mandatory affordance of it.

    Only local models are read; a remote one gets a single warning, because td2adaptor works offline.
    """
    data = td_doc.data
    if not isinstance(data, dict) or is_thing_model(data) or not isinstance(data.get("links"), list):
        return
    resolver = Resolver(td_doc, diags, remote_severity=Severity.WARNING)
    for i, link in enumerate(data["links"]):
        if not (isinstance(link, dict) and link.get("rel") == "type" and isinstance(link.get("href"), str)):
            continue
        href: str = link["href"]
        ptr = pointer_join("", "links", i, "href")
        kind, path = resolver.classify(href, resolver.root_key)
        if kind != "local" or path is None:
            diags.warning(
                "TM350",
                f"linked Thing Model {href} not fetched (offline); conformance to it not checked",
                ptr,
            )
            continue
        key = resolver.load(path, resolver.root_key, ptr, "linked Thing Model")
        if key is None:
            continue
        tm_doc = resolver.docs[key]
        if tm_doc is None or not isinstance(tm_doc.data, dict):
            diags.error("TM351", f"linked Thing Model {href} is not a JSON object", ptr)
            continue
        model = resolver.model(key)
        optional = set(optional_affordances(model, None))
        _compare(model, data, optional, href, diags)


def _compare(
    model: Mapping[str, Any],
    td: Mapping[str, Any],
    optional: set[tuple[str, str]],
    href: str,
    diags: Diagnostics,
) -> None:
    """Report the model's mandatory affordances the TD lacks, and data types that contradict the model."""
    for kind in AFFORDANCE_KINDS:
        affs = model.get(kind)
        if not isinstance(affs, dict):
            continue
        td_affs = td.get(kind) if isinstance(td.get(kind), dict) else {}
        assert isinstance(td_affs, dict)
        for name, aff in affs.items():
            pattern = _name_pattern(name)
            matches = [n for n in td_affs if pattern.match(n)]
            if not matches:
                if (kind, name) not in optional:
                    diags.error(
                        "TM352",
                        f"{kind}/{name} of the linked Thing Model {href} is missing",
                        pointer_join("", kind) if kind in td else "",
                        "the model marks it mandatory (it is not in tm:optional)",
                    )
                continue
            for td_name in matches:
                _compare_types(kind, td_name, aff, td_affs[td_name], href, diags)


def _compare_types(kind: str, td_name: str, aff: Any, td_aff: Any, href: str, diags: Diagnostics) -> None:
    """A TD may narrow the model (integer for number) but not contradict its data types."""
    if not isinstance(aff, dict) or not isinstance(td_aff, dict):
        return
    want = dict(_data_type(kind, aff))
    for member, got in _data_type(kind, td_aff):
        expected = want.get(member)
        if not isinstance(expected, str) or "{{" in expected or not isinstance(got, str):
            continue
        if got != expected and not (expected == "number" and got == "integer"):
            diags.error(
                "TM353",
                f"{kind}/{td_name} has type {got!r}, the linked Thing Model {href} says {expected!r}",
                pointer_join("", kind, td_name, *(() if member == "type" else (member,)), "type"),
            )
