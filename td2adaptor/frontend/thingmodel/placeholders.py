"""`{{NAME}}` substitution over a model, typed where a string is exactly one placeholder."""

from __future__ import annotations

import copy
import re
from collections.abc import Collection, Mapping
from typing import Any

from td2adaptor.diagnostics import pointer_join
from td2adaptor.frontend.thingmodel.common import (
    MISSING,
    PLACEHOLDER,
    compact,
)


class Substitution:
    """One pass of `{{NAME}}` substitution over a model, remembering what was missing, kept and used."""

    def __init__(self, values: Mapping[str, Any], keep: Collection[str]) -> None:
        self.values = values
        self.keep = set(keep)
        self.missing: dict[str, list[str]] = {}  # name -> every place it is used, in model order
        self.kept: dict[str, str] = {}
        self.used: set[str] = set()
        self.collisions: list[tuple[str, str]] = []

    def name_of(self, match: re.Match[str]) -> str:
        return match.group(1).strip()

    def lookup(self, name: str, pointer: str) -> Any:
        if name in self.values:
            self.used.add(name)
            return self.values[name]
        if name in self.keep:
            self.kept.setdefault(name, pointer)
        else:
            places = self.missing.setdefault(name, [])
            if pointer not in places:
                places.append(pointer)
        return MISSING

    def text(self, s: str, pointer: str) -> str:
        def repl(m: re.Match[str]) -> str:
            name = self.name_of(m)
            value = self.lookup(name, pointer) if name else MISSING
            return m.group(0) if value is MISSING else compact(value)

        return PLACEHOLDER.sub(repl, s)

    def value(self, v: Any, pointer: str) -> Any:
        if isinstance(v, str):
            whole = PLACEHOLDER.fullmatch(v)
            if whole and self.name_of(whole):
                found = self.lookup(self.name_of(whole), pointer)
                return v if found is MISSING else copy.deepcopy(found)
            return self.text(v, pointer)
        if isinstance(v, list):
            return [self.value(item, pointer_join(pointer, i)) for i, item in enumerate(v)]
        if isinstance(v, dict):
            out: dict[str, Any] = {}
            for key, item in v.items():
                ptr = pointer_join(pointer, key)
                new_key = self.text(key, ptr)
                if new_key in out:
                    self.collisions.append((ptr, new_key))
                out[new_key] = self.value(item, ptr)
            return out
        return v
