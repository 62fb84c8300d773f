"""Thing Model constants and the small JSON helpers every step of instantiation uses."""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Mapping, Sequence
from typing import Any

from td2adaptor.diagnostics import pointer_tokens

TM_TYPE = "tm:ThingModel"
TM_TYPE_IRI = "https://www.w3.org/2019/wot/tm#ThingModel"
TD_CONTEXT_V1 = "https://www.w3.org/2019/wot/td/v1"
TD_CONTEXT_V11 = "https://www.w3.org/2022/wot/td/v1.1"
TM_MEDIA_TYPE = "application/tm+json"
AFFORDANCE_KINDS = ("properties", "actions", "events")
# `{{NAME}}`: printable ASCII as the TM schema's placeholder-pattern says, but no braces, so that
# "{{A}} and {{B}}" is two placeholders, not one named "A}} and {{B"
PLACEHOLDER = re.compile(r"\{\{([ -z|~]+)\}\}")
MISSING: Any = object()


def is_thing_model(data: object) -> bool:
    """True if `@type` declares a Thing Model: that is what tells a TM from a TD."""
    if not isinstance(data, Mapping):
        return False
    types = data.get("@type")
    items = types if isinstance(types, list) else [types]
    return any(t in (TM_TYPE, TM_TYPE_IRI) for t in items)


def merge_patch(target: Any, patch: Any) -> Any:
    """RFC 7396 JSON Merge Patch, without touching either argument."""
    if not isinstance(patch, dict):
        return copy.deepcopy(patch)
    result: dict[str, Any] = dict(target) if isinstance(target, dict) else {}
    for key, value in patch.items():
        if value is None:
            result.pop(key, None)
        else:
            result[key] = merge_patch(result.get(key), value)
    return result


def lookup(data: Any, pointer: str) -> Any:
    """The value at a JSON pointer, or `MISSING`."""
    node = data
    for tok in pointer_tokens(pointer):
        if isinstance(node, dict) and tok in node:
            node = node[tok]
        elif isinstance(node, list) and tok.isdigit() and int(tok) < len(node):
            node = node[int(tok)]
        else:
            return MISSING
    return node


def as_list(value: Any) -> list[Any]:
    return list(value) if isinstance(value, list) else [value]


def union(first: Any, second: Any) -> Any:
    """Ordered union of two values that may each be a list or a single item (a single item stays single)."""
    out: list[Any] = []
    for item in as_list(first) + as_list(second):
        if item not in out:
            out.append(copy.deepcopy(item))
    if len(out) == 1 and not isinstance(first, list) and not isinstance(second, list):
        return out[0]
    return out


def compact(value: Any) -> str:
    """How a value reads inside a string: strings as they are, anything else as compact JSON."""
    if isinstance(value, str):
        return value
    return json.dumps(value, separators=(",", ":"), ensure_ascii=False)


def join_names(names: Sequence[str]) -> str:
    return ", ".join(names)
