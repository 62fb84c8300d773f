"""Deterministic JSON text for generated files and published documents."""

from __future__ import annotations

import json
from typing import Any

import orjson


def dump(data: Any) -> str:
    """Deterministic JSON text: insertion order (TD order), two-space indent, final newline.

    orjson writes the layout of `json.dumps(indent=2, ensure_ascii=False)` (a test holds them equal; only a
    float's exponent may be spelled differently, both exact) ten times faster, which matters with one schema
    file per event; what orjson refuses (integers beyond 64 bits, very deep nesting) goes through `json`.
    """
    try:
        return orjson.dumps(data, option=orjson.OPT_INDENT_2 | orjson.OPT_APPEND_NEWLINE).decode("utf-8")
    except (orjson.JSONEncodeError, RecursionError):
        return json.dumps(data, indent=2, ensure_ascii=False) + "\n"
