"""Running a one-shot CLI command without Python's cyclic garbage collector.

`gen` builds objects that nearly all live until it ends: the TD, the model, every generated tree. Each
full collection walks all of them, and the larger the TD the more of them each walk finds: collecting took
about a quarter of the CPU time of `gen` of a 10,000-affordance TD (7.6 s with the collector, 5.5 s without,
in one process), a share that grows with the TD, so `gen` grew faster than it. Reference counting still
frees what the command drops; only reference cycles wait, and a command makes few (about 30,000 small
objects for 10,000 affordances), freed when the collector runs again after it.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused() -> Iterator[None]:
    """The collector off inside, as it was after (for commands that end; never around the edge node)."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
