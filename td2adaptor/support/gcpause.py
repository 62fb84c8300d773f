"""Running a one-shot CLI command without Python's cyclic garbage collector, and the edge node's start-up
objects set aside from its full passes.

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


def freeze_startup() -> None:
    """Set what a long-running process made while starting aside from the collector's full passes (after one
    collection, so that start-up's garbage is freed, not kept): `gc.freeze()`.

    A full (generation 2) pass walks every object the collector tracks while every other thread waits for the
    GIL. The edge node's start-up leaves about 120,000 of them for 100 RB-1s (modules, the model, ROS message
    types, each robot's engine), nearly all alive until it stops: each full pass under load took 50-75 ms of
    CPU, and every mission in flight waited as long (the fleet's p99 latency). Frozen, they are no longer
    walked; only what was made since is. Objects frozen are never collected: a cycle start-up leaves and drops
    later stays in memory (rare: the engines live as long as the process)."""
    gc.collect()
    gc.freeze()
