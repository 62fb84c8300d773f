"""Loaded into td2adaptor subprocesses by the determinism test: directory listings come back shuffled.

Not part of td2adaptor. The seed comes from TD2A_SHUFFLE_SEED, so each run sees a different order.
"""

from __future__ import annotations

import os
import random
from pathlib import Path

_rng = random.Random(os.environ.get("TD2A_SHUFFLE_SEED", "0"))
_listdir, _scandir, _iterdir = os.listdir, os.scandir, Path.iterdir


def _shuffled(items):  # type: ignore[no-untyped-def]
    items = list(items)
    _rng.shuffle(items)
    return items


class _Scandir:
    def __init__(self, path):  # type: ignore[no-untyped-def]
        self._it = _scandir(path)
        self._entries = _shuffled(self._it)

    def __iter__(self):  # type: ignore[no-untyped-def]
        return self

    def __next__(self):  # type: ignore[no-untyped-def]
        if not self._entries:
            raise StopIteration
        return self._entries.pop()

    def __enter__(self):  # type: ignore[no-untyped-def]
        return self

    def __exit__(self, *exc):  # type: ignore[no-untyped-def]
        self._it.close()

    def close(self) -> None:
        self._it.close()


os.listdir = lambda path=".": _shuffled(_listdir(path))  # type: ignore[assignment]
os.scandir = _Scandir  # type: ignore[assignment,misc]
Path.iterdir = lambda self: iter(_shuffled(_iterdir(self)))  # type: ignore[method-assign]
