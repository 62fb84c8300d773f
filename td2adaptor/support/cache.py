"""A per-user cache directory for data that is expensive to derive and depends only on its key.

`TD2ADAPTOR_CACHE_DIR` chooses the directory, `TD2ADAPTOR_NO_CACHE=1` turns caching off; otherwise
`$XDG_CACHE_HOME/td2adaptor` or `~/.cache/td2adaptor`. Every failure to read or write is ignored: the
cache can only make things faster, never change a result.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def cache_dir() -> Path | None:
    if os.environ.get("TD2ADAPTOR_NO_CACHE"):
        return None
    explicit = os.environ.get("TD2ADAPTOR_CACHE_DIR")
    if explicit:
        return Path(explicit)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "td2adaptor"


def read_json(name: str) -> Any:
    directory = cache_dir()
    if directory is None:
        return None
    try:
        with (directory / name).open(encoding="utf-8") as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def write_json(name: str, data: Any) -> None:
    directory = cache_dir()
    if directory is None:
        return
    try:
        from td2adaptor.support.fsutil import write_atomic

        write_atomic(directory / name, json.dumps(data, separators=(",", ":")).encode("utf-8"))
    except OSError:
        pass
