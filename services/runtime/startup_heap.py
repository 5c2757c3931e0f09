"""Keep the objects of a service's start-up out of the garbage collector's full passes.

A started service holds some hundred thousand long-lived container objects (modules,
numba dispatchers, pydantic schemas, Zenoh bindings). CPython's cyclic collector
traverses all of them in every generation-2 pass: in the fusion service at 20,000
plots/s that was 11 passes of 14–53 ms in a 30 s run, each one a stall of the main loop
(docs/performance.md, "Garbage-collector passes"). :func:`freeze_startup_heap`, called
once the service is ready and before it takes traffic, collects what start-up left
behind and moves every surviving object to the permanent generation (``gc.freeze``,
Python ≥ 3.7): they are still freed by reference counting, only the cycle search skips
them. Objects created afterwards (tracks, batches, messages) are collected as before.
"""

from __future__ import annotations

import gc
import logging

log = logging.getLogger(__name__)


def freeze_startup_heap() -> int:
    """Collect, then freeze every object alive now; returns how many are frozen."""
    gc.collect()
    gc.freeze()
    n = gc.get_freeze_count()
    log.debug("start-up heap frozen: %d objects", n)
    return n
