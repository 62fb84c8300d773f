"""Find `schemas/` and `templates/`: packaged as `td2adaptor/_data/` in a wheel, at the repo root in a checkout."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from typing import Any

_PKG = Path(__file__).resolve().parent


@cache
def data_dir(name: str) -> Path:
    """The directory `schemas` or `templates`, wherever this installation keeps it."""
    for candidate in (_PKG / "_data" / name, _PKG.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"td2adaptor installation is incomplete: no {name}/ directory found")


def schema_path(filename: str) -> Path:
    return data_dir("schemas") / filename


@cache
def load_schema(filename: str) -> Any:
    """A bundled JSON (or JSON-LD) file from `schemas/`, parsed once per process."""
    with schema_path(filename).open(encoding="utf-8") as fh:
        return json.load(fh)
