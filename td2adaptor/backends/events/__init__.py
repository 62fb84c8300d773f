"""The events backend: the event contract of an adaptor: event JSON Schemas, an AsyncAPI document, the exposed TD.

`generator.py` computes everything; `templates/` holds only what varies.
"""

from __future__ import annotations

from td2adaptor.backends.events.generator import finish, generate

NAME = "events"
DISTRO: str | None = None
ORDER = 90

__all__ = ["DISTRO", "NAME", "ORDER", "finish", "generate"]
