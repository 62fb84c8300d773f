"""`tm:optional`: which affordances a model marks optional, and dropping those not selected."""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Mapping
from typing import Any

from td2adaptor.diagnostics import Diagnostics, pointer_join, pointer_tokens
from td2adaptor.frontend.thingmodel.common import (
    AFFORDANCE_KINDS,
    join_names,
)


def optional_affordances(
    model: Mapping[str, Any], report: Callable[[str, str, str], None] | None
) -> list[tuple[str, str]]:
    """(kind, name) of the affordances `tm:optional` names; bad entries are reported if `report` is given."""
    entries = model.get("tm:optional")
    if entries is None:
        return []
    if not isinstance(entries, list):
        if report:
            report(
                "TM330",
                'tm:optional must be an array of JSON pointers such as "/properties/battery"',
                "/tm:optional",
            )
        return []
    out: list[tuple[str, str]] = []
    for i, entry in enumerate(entries):
        ptr = pointer_join("", "tm:optional", i)
        if not isinstance(entry, str):
            if report:
                report("TM330", f"tm:optional entry {json.dumps(entry)} is not a JSON pointer string", ptr)
            continue
        tokens = pointer_tokens(entry[1:] if entry.startswith("#") else entry)
        if (
            len(tokens) == 2
            and tokens[0] in AFFORDANCE_KINDS
            and isinstance(model.get(tokens[0]), dict)
            and tokens[1] in model[tokens[0]]
        ):
            if (tokens[0], tokens[1]) not in out:
                out.append((tokens[0], tokens[1]))
        elif report:
            report(
                "TM331",
                f"tm:optional entry {entry!r} does not point to an affordance of the model",
                ptr,
            )
    return out


def select_optional(
    model: dict[str, Any],
    include_optional: bool | Collection[str],
    error: Callable[[str, str, str], None],
    diags: Diagnostics,
) -> None:
    """Drop the optional affordances that were not asked for, and the `tm:optional` key itself."""
    optional = optional_affordances(model, error)
    model.pop("tm:optional", None)
    if include_optional is True:
        return
    selected: set[tuple[str, str]] = set()
    if include_optional is not False:
        wanted = [include_optional] if isinstance(include_optional, str) else list(include_optional)
        for item in wanted:
            if item.startswith(("/", "#/")):
                tokens = pointer_tokens(item[1:] if item.startswith("#") else item)
                matches = [o for o in optional if len(tokens) == 2 and o == (tokens[0], tokens[1])]
            else:
                matches = [o for o in optional if o[1] == item]
            if not matches:
                declared = join_names([f"/{k}/{n}" for k, n in optional]) or "none"
                error("TM332", f"{item!r} is not an optional affordance of the model (optional: {declared})", "")
            selected.update(matches)
    dropped = [o for o in optional if o not in selected]
    for kind, name in dropped:
        model[kind].pop(name, None)
    if dropped:
        diags.info("TM333", "optional affordances left out: " + join_names([f"/{k}/{n}" for k, n in dropped]))
