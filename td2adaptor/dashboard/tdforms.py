"""What a robot's Thing Description names: the topics to listen on (observable properties, events) and the
topics its forms publish to (write a property, invoke, query or cancel an action). The dashboard publishes only
on these, and only under the robot's own topics, whatever a page asks for."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import urlsplit

#: the page's words for an action's operations, and the TD 1.1 operation of each
ACTION_OPS = {"invoke": "invokeaction", "query": "queryaction", "cancel": "cancelaction"}
WRITE_OP = "writeproperty"


@dataclass
class Affordances:
    """A robot's topics as its TD names them."""

    properties: dict[str, str] = field(default_factory=dict)  # topic -> observable property
    events: dict[str, str] = field(default_factory=dict)  # topic -> event
    publish: dict[tuple[str, str], str] = field(default_factory=dict)  # (affordance, TD operation) -> topic


def form_topic(form: Mapping[str, Any]) -> str | None:
    """The MQTT topic of a form: `mqv:topic` / `mqv:filter` (W3C MQTT binding), else the href's path."""
    for key in ("mqv:topic", "mqv:filter"):
        value = form.get(key)
        if isinstance(value, str) and value:
            return value
    href = form.get("href")
    if not isinstance(href, str):
        return None
    try:
        path = urlsplit(href).path.lstrip("/")
    except ValueError:
        return None
    return path or None


def _ops(form: Mapping[str, Any]) -> list[str]:
    op = form.get("op")
    return [op] if isinstance(op, str) else [o for o in op if isinstance(o, str)] if isinstance(op, list) else []


def _forms(affordance: Any) -> list[Mapping[str, Any]]:
    """An affordance's forms (one form alone: a TD a directory gave back as JSON-LD framed from RDF)."""
    forms = affordance.get("forms") if isinstance(affordance, Mapping) else None
    forms = [forms] if isinstance(forms, Mapping) else forms
    return [f for f in forms if isinstance(f, Mapping)] if isinstance(forms, list) else []


def affordances(td: Mapping[str, Any], prefix: str) -> Affordances:
    """The topics of `td` under `prefix` (`<root>/<robot>/`): a topic elsewhere is another robot's or nobody's,
    and a page must not reach it through a TD that names it."""
    out = Affordances()

    def kept(topic: str | None) -> str | None:
        return topic if topic is not None and topic.startswith(prefix) and "#" not in topic else None

    for kind, listen in (("properties", "observeproperty"), ("events", "subscribeevent")):
        group = td.get(kind)
        if not isinstance(group, Mapping):
            continue
        for name, affordance in group.items():
            for form in _forms(affordance):
                ops = _ops(form)
                topic = kept(form_topic(form))
                if topic is None:
                    continue
                if listen in ops and "+" not in topic:
                    (out.properties if kind == "properties" else out.events)[topic] = str(name)
                if WRITE_OP in ops:
                    out.publish[(str(name), WRITE_OP)] = topic
    actions = td.get("actions")
    if isinstance(actions, Mapping):
        for name, affordance in actions.items():
            for form in _forms(affordance):
                topic = kept(form_topic(form))
                for op in _ops(form):
                    if topic is not None and op in ACTION_OPS.values() and "+" not in topic:
                        out.publish.setdefault((str(name), op), topic)
    return out
