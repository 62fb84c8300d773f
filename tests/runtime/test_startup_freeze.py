"""The edge node's start-up objects are set aside from the garbage collector's full passes
(support/gcpause.py `freeze_startup`, called by `td2adaptor run` once every robot is started)."""

from __future__ import annotations

import gc
import weakref

from td2adaptor.support.gcpause import freeze_startup


class _Node:
    """An object in a reference cycle (only the cyclic collector frees it)."""

    def __init__(self) -> None:
        self.me = self


def test_start_up_objects_are_not_walked_by_full_passes_and_start_up_garbage_is_freed_first() -> None:
    kept = [_Node() for _ in range(1_000)]  # what start-up keeps: every robot's engine
    dropped = _Node()  # a cycle start-up made and let go: it must be freed, not frozen
    gone = weakref.ref(dropped)
    del dropped
    try:
        freeze_startup()
        assert gone() is None, "start-up's garbage was frozen instead of freed"
        walked = {id(o) for o in gc.get_objects(generation=2)}
        assert not any(id(node) in walked for node in kept), "a full pass still walks the start-up objects"
        assert gc.get_freeze_count() >= len(kept)
        later = _Node()  # made after start-up: collected as before
        later_gone = weakref.ref(later)
        del later
        gc.collect()
        assert later_gone() is None
    finally:
        gc.unfreeze()  # the test process's other tests see the collector as it was
