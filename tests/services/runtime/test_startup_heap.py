"""``freeze_startup_heap``: what start-up left as garbage is collected, not frozen; what is
alive is frozen (skipped by later full passes) and still freed by reference counting."""

from __future__ import annotations

import gc
import weakref

from skyfuse.services.runtime.startup_heap import freeze_startup_heap


class _Node:
    pass


def test_garbage_is_collected_and_the_live_heap_frozen():
    gc.unfreeze()
    cycle = _Node()
    cycle.me = cycle  # unreachable once dropped: only the cycle search frees it
    dead = weakref.ref(cycle)
    del cycle
    live = _Node()
    try:
        n = freeze_startup_heap()
        assert dead() is None  # collected before the freeze, so not kept forever
        assert n == gc.get_freeze_count() > 0
        assert not any(o is live for o in gc.get_objects())  # frozen: out of the generations
        alive = weakref.ref(live)
        del live
        assert alive() is None  # reference counting still frees a frozen object
    finally:
        gc.unfreeze()
