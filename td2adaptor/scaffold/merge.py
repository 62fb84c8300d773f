"""`--merge`: fold a fresh scaffold into an existing TD without losing what a person wrote.

Affordances are matched by their ROS name (`rosv:name` of the first form), not by affordance name, so a
hand-chosen name survives. From the existing TD are kept: every Thing-level member, affordance names,
titles, descriptions, semantic annotations (`@type`, any prefixed term, `rosv:component`,
`rosv:procedure`), `safe`/`idempotent`, extra forms and form members the scaffold does not own, and the
titles, descriptions, units and enums inside data schemas (wherever the existing TD has the schema, also
when it has none of them: the scaffold's texts and enums go only into what is new), and the constraints
inside them that the ROS types do not contradict (`constraints`: the limits the edge node enforces; what was
kept and what dropped, and why, is said: SCF113, SCF114). From the source come the ROS binding (type, role,
interface, QoS) and the data schemas' structure. Existing affordances the source does not show are kept
(SCF109); new ones are added.
"""

from __future__ import annotations

import json
from typing import Any

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.scaffold.constraints import CONSTRAINTS, Change, gone, lay_over

SECTIONS = ("properties", "actions", "events")
#: form members the scaffold writes (the rest of an existing form is the user's)
_OWNED_FORM_KEYS = frozenset({"href", "op", "rosv:name", "rosv:type", "rosv:interface", "rosv:role", "rosv:latch"})
#: data schema members that describe rather than constrain: always the existing TD's
_ANNOTATIONS = frozenset({"title", "titles", "description", "descriptions", "unit", "@type", "comment", "default"})
#: what the existing TD decides wherever it has the schema, also by leaving it out: its texts, and `enum` (the
#: scaffold's, from a message's constants, may be narrower than what the robot sends)
_PERSONS = _ANNOTATIONS | {"enum"}
#: affordance members a person decides: the existing TD's when it has them
_DECIDED = frozenset({"safe", "idempotent"})


def _rosname(affordance: Any) -> str | None:
    forms = affordance.get("forms") if isinstance(affordance, dict) else None
    if isinstance(forms, list) and forms and isinstance(forms[0], dict):
        name = forms[0].get("rosv:name")
        return name if isinstance(name, str) else None
    return None


def merge_schema(old: Any, new: Any, where: str = "", changes: list[Change] | None = None) -> Any:
    """`new`'s structure with `old`'s annotations, and the constraints of `old` that `new` (the ROS type's
    schema) does not contradict, wherever the two share a path (`where`: its JSON pointer, for `changes`)."""
    if not isinstance(old, dict) or not isinstance(new, dict):
        return new
    changes = [] if changes is None else changes
    out = {k: v for k, v in new.items() if k not in _PERSONS}
    for key, value in old.items():
        if key in _PERSONS or (":" in key and key not in out):
            out[key] = value
    lay_over(old, new, out, where, changes)
    for key in ("items", "input", "output"):
        if key in old and key in new:
            out[key] = merge_schema(old[key], new[key], f"{where}/{key}", changes)
    old_props, new_props = old.get("properties"), new.get("properties")
    if isinstance(old_props, dict) and isinstance(new_props, dict):
        at = f"{where}/properties"
        out["properties"] = {k: merge_schema(old_props.get(k), v, f"{at}/{k}", changes) for k, v in new_props.items()}
        for name, sub in old_props.items():
            if name not in new_props and isinstance(sub, dict):
                gone(sub, f"{at}/{name}", changes)
    return out


def _merge_form(old: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    out = {k: v for k, v in old.items() if k not in _OWNED_FORM_KEYS and k != "rosv:qos"}
    out.update(new)
    old_qos, new_qos = old.get("rosv:qos"), new.get("rosv:qos")
    if isinstance(old_qos, dict):
        out["rosv:qos"] = {**old_qos, **(new_qos or {})}
    return out


def _merge_affordance(old: dict[str, Any], new: dict[str, Any], where: str, changes: list[Change]) -> dict[str, Any]:
    mine = {k: v for k, v in old.items() if k != "forms"}
    out = merge_schema(mine, {k: v for k, v in new.items() if k != "forms"}, where, changes)
    for key in ("rosv:component", "rosv:procedure", *_DECIDED):
        if key in old:
            out[key] = old[key]
    for key, value in old.items():  # the user's own members (semantic annotations, links, uriVariables...)
        if key not in out and key != "forms" and key not in CONSTRAINTS:  # constraints: merge_schema decided
            out[key] = value
    forms = old.get("forms")
    old_forms: list[Any] = forms if isinstance(forms, list) else []
    first = old_forms[0] if old_forms and isinstance(old_forms[0], dict) else {}
    merged: dict[str, Any] = out
    merged["forms"] = [_merge_form(first, new["forms"][0]), *old_forms[1:]]
    return merged


def merge(existing: dict[str, Any], fresh: dict[str, Any], diags: Diagnostics) -> dict[str, Any]:
    """`existing` updated from `fresh` (both TD-shaped JSON objects)."""
    index: dict[str, tuple[str, str]] = {}
    for section in SECTIONS:
        for name, aff in (existing.get(section) or {}).items():
            rosname = _rosname(aff)
            if rosname is not None:
                index.setdefault(rosname, (section, name))
    taken = {name for section in SECTIONS for name in (existing.get(section) or {})}
    renames: dict[str, str] = {}
    matched: dict[tuple[str, str], tuple[str, dict[str, Any]]] = {}
    added: dict[str, dict[str, Any]] = {s: {} for s in SECTIONS}
    for section in SECTIONS:
        for name, aff in (fresh.get(section) or {}).items():
            hit = index.get(_rosname(aff) or "")
            if hit is not None and hit not in matched:
                matched[hit] = (name, aff)
                renames[name] = hit[1]
                continue
            final, n = name, 2
            while final in taken:
                final, n = f"{name}{n}", n + 1
            taken.add(final)
            renames[name] = final
            added[section][final] = aff
    out = {k: v for k, v in existing.items() if k not in SECTIONS}
    changes: list[Change] = []
    for key, value in fresh.items():
        if key not in SECTIONS and key not in out:
            out[key] = value
    for section in SECTIONS:
        merged: dict[str, Any] = {}
        for name, aff in (existing.get(section) or {}).items():
            if (section, name) in matched:
                fresh_aff = _renamed(matched[(section, name)][1], renames)
                merged[name] = _merge_affordance(aff, fresh_aff, f"/{section}/{name}", changes)
            else:
                merged[name] = aff
                if isinstance(aff, dict) and _rosname(aff) is not None:
                    diags.warning("SCF109", f"{section}/{name} ({_rosname(aff)}) is not in the source: kept as it is")
        for name, aff in added[section].items():
            merged[name] = _renamed(aff, renames)
        if merged:
            out[section] = merged
    _say(changes, diags)
    return out


def _say(changes: list[Change], diags: Diagnostics) -> None:
    """One warning per dropped constraint (with the ROS type's reason), one line naming the kept ones."""
    for change in changes:
        if change.reason is not None:
            what = change.pointer.rsplit("/", 1)[-1]
            diags.warning(
                "SCF114",
                f"hand-written {what} {json.dumps(change.value)} dropped: {change.reason}",
                change.pointer,
            )
    kept = [c.pointer for c in changes if c.reason is None]
    if kept:
        dropped = len(changes) - len(kept)
        diags.info(
            "SCF113",
            f"kept {len(kept)} hand-written constraint{'s' * (len(kept) != 1)} the ROS types allow "
            f"({dropped} dropped): {', '.join(kept)}",
        )


def _renamed(aff: dict[str, Any], renames: dict[str, str]) -> dict[str, Any]:
    procedure = aff.get("rosv:procedure")
    if not isinstance(procedure, dict):
        return aff
    linked = {k: renames.get(v, v) if k in ("query", "cancel") else v for k, v in procedure.items()}
    return {**aff, "rosv:procedure": linked}
