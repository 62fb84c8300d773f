"""The JSON Schemas and JSON-LD contexts the front end bundles (`frontend/schemas/`), so nothing is fetched."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

SCHEMAS = Path(__file__).resolve().parent / "schemas"


def schema_path(filename: str) -> Path:
    return SCHEMAS / filename


@cache
def load_schema(filename: str) -> Any:
    """A bundled JSON (or JSON-LD) file, parsed once per process."""
    with schema_path(filename).open(encoding="utf-8") as fh:
        return json.load(fh)
