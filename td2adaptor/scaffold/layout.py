"""From endpoints to affordances: the robot namespace(s), names, components and procedure links.

Decisions a person would otherwise make by hand, made the same way every time:

* robot namespace: the first name segment under which the robot's endpoints sit (`/rb1_base_a/...`); its
  endpoints are written `/{{robotName}}/...`. Several namespaces holding the same interfaces are a fleet:
  one Thing Model for all of them.
* procedures: services `<P>/add`, `<P>/query_state`, `<P>/cancel` (the robot_local_control pattern, and
  `run`/`query`/`cancel`) become `<p>Run`/`<p>Query`/`<p>Cancel` in one component `<P>` with `rosv:procedure`.
* names: lowerCamelCase of the last name segment, more segments while two would collide.
* components: a procedure's prefix; otherwise the node (`--group node`) or the name prefix shared by several
  affordances (`--group prefix`, the default), else one component per affordance.
"""

from __future__ import annotations

import keyword
import re
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

from td2adaptor.diagnostics import Diagnostics
from td2adaptor.scaffold.graph import Endpoint

Group = Literal["prefix", "node"]
PLACEHOLDER = "{{robotName}}"

#: leaves of a procedure's services: run, query, cancel
_PROCEDURE_LEAVES = (("add", "query_state", "cancel"), ("run", "query", "cancel"))
#: words the generated C++/Python must not meet as method names
_RESERVED = frozenset({"class", "delete", "new", "default", "register", "template", "this", "operator", "union"})


@dataclass
class Plan:
    """One affordance to write."""

    section: Literal["properties", "actions"]
    name: str
    component: str
    endpoint: Endpoint
    rosname: str
    href: str
    procedure: dict[str, Any] | None = None
    safe: bool = False


@dataclass
class Layout:
    plans: list[Plan]
    namespaces: list[str]

    @property
    def fleet(self) -> bool:
        return len(self.namespaces) > 1


def _first(name: str) -> str | None:
    parts = name.strip("/").split("/")
    return parts[0] if len(parts) > 1 else None


def _relative(ep: Endpoint, ns: str) -> str:
    return ep.name[len(ns) + 2 :]


Signature = frozenset[tuple[str, str, str, str]]


def _signatures(endpoints: Sequence[Endpoint]) -> dict[str, Signature]:
    """What each first name segment holds, as (kind, name below it, type, role): one pass over the graph."""
    found: dict[str, set[tuple[str, str, str, str]]] = defaultdict(set)
    for e in endpoints:
        ns = _first(e.name)
        if ns is not None:
            found[ns].add((e.kind, _relative(e, ns), e.type, e.role))
    return {ns: frozenset(items) for ns, items in found.items()}


def robot_namespaces(endpoints: Sequence[Endpoint], given: Sequence[str], diags: Diagnostics) -> list[str]:
    """The robot namespace(s): given ones, else several with the same interfaces (a fleet), else the one
    holding most endpoints when it holds at least two and at least half of them, else none."""
    if given:
        chosen = [g.strip("/") for g in given if g.strip("/")]
        deep = [ns for ns in chosen if "/" in ns]
        if deep:
            diags.error(
                "SCF112",
                f"robot namespace {', '.join(deep)} has several segments: {PLACEHOLDER} stands for the first "
                "segment of a name only",
                hint="give one segment (e.g. rb1_base_a): robotName is also the robot id and its MQTT topic root",
            )
            return []
        return chosen
    counts = Counter(ns for e in endpoints if (ns := _first(e.name)) is not None)
    signatures = _signatures(endpoints)
    groups: dict[Signature, list[str]] = defaultdict(list)
    for ns in counts:
        if counts[ns] >= 2:
            groups[signatures[ns]].append(ns)
    fleets = sorted((sorted(nss) for nss in groups.values() if len(nss) > 1), key=lambda g: (-len(g), g))
    if fleets:
        return fleets[0]
    if counts:
        ns, n = max(sorted(counts.items()), key=lambda item: item[1])
        if n >= 2 and 2 * n >= len(endpoints):
            return [ns]
    return []


def _fleet_endpoints(endpoints: Sequence[Endpoint], namespaces: list[str], diags: Diagnostics) -> list[Endpoint]:
    """Endpoints of the first robot that every robot has, plus those outside every robot namespace."""
    first = namespaces[0]
    signatures = _signatures(endpoints)
    common = signatures.get(first, frozenset())
    for ns in namespaces[1:]:
        other = signatures.get(ns, frozenset())
        if other != common:
            differ = sorted(n for _, n, _, _ in common ^ other)
            diags.warning(
                "SCF104",
                f"robot namespaces {first} and {ns} differ ({', '.join(differ[:5])}"
                f"{', ...' if len(differ) > 5 else ''}): the Thing Model has only what they share",
            )
            common &= other
    kept = [e for e in endpoints if _first(e.name) == first and (e.kind, _relative(e, first), e.type, e.role) in common]
    robots = set(namespaces)
    return kept + [e for e in endpoints if _first(e.name) not in robots]


def words(text: str) -> list[str]:
    """`GoToComponent` → [Go, To, Component]; `ar_pose_marker` → [ar, pose, marker]."""
    return [
        w for part in re.split(r"[^A-Za-z0-9]+", text) for w in re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z0-9]+", part)
    ]


def camel(parts: Sequence[str], *, upper: bool = False) -> str:
    ws = [w for p in parts for w in words(p)]
    if not ws:
        return "Affordance" if upper else "affordance"
    text = "".join(w[:1].upper() + w[1:] for w in ws)
    text = text if upper else text[:1].lower() + text[1:]
    if text[0].isdigit():
        text = ("N" if upper else "n") + text
    return text


def _component_name(segment: str) -> str:
    base = camel([segment], upper=True)
    return base if base.endswith("Component") else base + "Component"


def _names(stems: dict[int, list[str]]) -> dict[int, str]:
    """lowerCamelCase names from the last segments, using more segments while names collide."""
    depth = dict.fromkeys(stems, 1)
    while True:
        names = {i: camel(segs[-depth[i] :]) for i, segs in stems.items()}
        clash = Counter(names.values())
        grow = [i for i, n in names.items() if clash[n] > 1 and depth[i] < len(stems[i])]
        if not grow:
            break
        for i in grow:
            depth[i] += 1
    out: dict[int, str] = {}
    used: set[str] = set()
    for i in sorted(names):
        name = names[i]
        if keyword.iskeyword(name) or name in _RESERVED:
            name += "Value"
        candidate, n = name, 2
        while candidate in used:
            candidate, n = f"{name}{n}", n + 1
        used.add(candidate)
        out[i] = candidate
    return out


def plan(endpoints: Sequence[Endpoint], namespaces: list[str], group: Group, diags: Diagnostics) -> Layout:
    """The affordances for `endpoints` (already selected) under robot `namespaces`."""
    if len(namespaces) > 1:
        endpoints = _fleet_endpoints(endpoints, namespaces, diags)
    ns = namespaces[0] if namespaces else None

    def local(ep: Endpoint) -> tuple[str, str, list[str]]:
        """(rosv:name, href, name segments as seen from the robot)."""
        if ns is not None and _first(ep.name) == ns:
            rel = _relative(ep, ns)
            return f"/{PLACEHOLDER}/{rel}", f"ros:{rel}", rel.split("/")
        return ep.name, f"ros:{ep.name}", ep.name.strip("/").split("/")

    # a topic both published and subscribed on the robot is read (the robot's output)
    published = {e.name for e in endpoints if e.kind == "topic" and e.role == "publisher"}
    chosen = [e for e in endpoints if not (e.kind == "topic" and e.role == "subscriber" and e.name in published)]
    services = {e.name: e for e in chosen if e.kind == "service"}
    procedures: dict[str, tuple[str, str, str]] = {}  # service name -> (prefix, stem, role in procedure)
    stems_used: Counter[str] = Counter()
    numbered: dict[str, int] = {}  # stems given a number, and the number
    for prefix in sorted({name.rsplit("/", 1)[0] for name in services}):
        for run, query, cancel in _PROCEDURE_LEAVES:
            trio = (f"{prefix}/{run}", f"{prefix}/{query}", f"{prefix}/{cancel}")
            if all(t in services for t in trio) and not any(t in procedures for t in trio):
                stem = "".join(words(prefix.rsplit("/", 1)[-1].removesuffix("Component"))).lower() or "procedure"
                stem = "n" + stem if stem[0].isdigit() else stem
                stems_used[stem] += 1
                if stems_used[stem] > 1:  # the same last segment under two prefixes
                    n = stems_used[stem]
                    stem = f"{stem}{n}"
                    numbered[stem] = n
                for part, full in zip(("Run", "Query", "Cancel"), trio, strict=True):
                    procedures[full] = (prefix, stem, part)

    plans: list[Plan] = []
    stems: dict[int, list[str]] = {}
    for ep in chosen:
        rosname, href, segments = local(ep)
        section: Literal["properties", "actions"] = "properties" if ep.kind == "topic" else "actions"
        plans.append(Plan(section, "", "", ep, rosname, href))
        if ep.name not in procedures:
            stems[len(plans) - 1] = segments
    names = _names(stems)
    fixed: set[str] = set()
    for i, p in enumerate(plans):
        if p.endpoint.name in procedures:
            prefix, stem, part = procedures[p.endpoint.name]
            p.name = stem + part
            p.component = _component_name(prefix.rsplit("/", 1)[-1])
            if stem in numbered:  # a second procedure of that name: its own component too
                p.component = f"{p.component.removesuffix('Component')}{numbered[stem]}Component"
            p.safe = part == "Query"
            if part == "Run":
                p.procedure = {"query": stem + "Query", "cancel": stem + "Cancel"}
            fixed.add(p.name)
        else:
            p.name = names[i]
    for p in plans:  # a plain affordance never takes a procedure's name
        if p.endpoint.name not in procedures and p.name in fixed:
            p.name += "Topic" if p.section == "properties" else "Service"
    _components(plans, procedures, group, local)
    order = {"Run": 0, "Cancel": 1, "Query": 2}
    plans.sort(
        key=lambda p: (
            p.section,
            p.component if p.endpoint.name in procedures else "",
            order.get(procedures.get(p.endpoint.name, ("", "", ""))[2], 9),
            p.rosname,
        )
    )
    return Layout(plans, namespaces)


def _components(plans: list[Plan], procedures: dict[str, Any], group: Group, local: Any) -> None:
    free = [p for p in plans if p.endpoint.name not in procedures]
    if group == "node":
        for p in free:
            node = p.endpoint.nodes[0].rsplit("/", 1)[-1] if p.endpoint.nodes else ""
            p.component = _component_name(node) if node else _component_name(p.name)
        return
    prefixes = Counter("/".join(local(p.endpoint)[2][:-1]) for p in free)
    taken = {p.component for p in plans if p.component}
    for p in free:
        prefix = "/".join(local(p.endpoint)[2][:-1])
        if prefix and prefixes[prefix] > 1:
            p.component = _component_name(prefix.rsplit("/", 1)[-1])
        else:
            p.component = _component_name(p.name)
        if p.component in taken and p.component != _component_name(p.name):
            p.component = _component_name(p.name)
