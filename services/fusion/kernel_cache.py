"""The tracker's compiled (numba) kernels and their on-disk cache: loading them, and
compiling them first with a line and a progress display when the cache is cold (``skyfuse
warmup``, ``skyfuse fusion`` and ``skyfuse demo`` all load them through here).

Where the cache is (numba's cache locators, tried in this order): ``NUMBA_CACHE_DIR``
when set and writable; else the ``__pycache__`` beside each kernel's module when the
package directory is writable (an editable or user install); else the user's cache
directory (``~/.cache/numba``: a package installed read-only for this user, e.g. by
root into site-packages). numba never reads a cache it cannot write, so a system-wide
install shared by several users compiles once per user unless ``NUMBA_CACHE_DIR`` names
a directory they can all write (the image: ``/opt/skyfuse/numba-cache``, owned by its
service user). With no writable place at all numba cannot load the kernels: the command
says so and exits 1.
"""

from __future__ import annotations

import logging
import sys
import time
from collections import Counter
from contextlib import contextmanager
from pathlib import Path

log = logging.getLogger("skyfuse.warmup")

COMPILING = "compiling tracker kernels (first run only)"

LOCATORS = {
    "UserProvidedCacheLocator": "NUMBA_CACHE_DIR",
    "InTreeCacheLocator": "in the package directory",
    "UserWideCacheLocator": "the user's cache directory: the package directory is read-only "
    "for this user (NUMBA_CACHE_DIR selects another)",
}
"""numba's cache locator classes → what they mean for a skyfuse install."""


def load_kernels(*, progress: bool | None = None) -> tuple[float, int]:
    """Load every tracker kernel (``fusion.tracker.kernel_warmup.warm_up``); when one is
    not in the cache, say ``compiling tracker kernels (first run only)`` (log line) and
    show the progress on a terminal (``progress``: force on or off). Returns (seconds,
    kernels compiled). Raises RuntimeError when numba finds no writable cache."""
    from skyfuse.fusion.tracker.kernel_warmup import warm_up

    show = sys.stderr.isatty() if progress is None else progress
    with _compile_progress(show) as compiled:
        seconds = warm_up()
    if compiled:
        log.info("tracker kernels compiled in %.1f s (%d kernels)", seconds, len(compiled))
    return seconds, len(compiled)


@contextmanager
def _compile_progress(show: bool):
    """Within: numba compilations (cache misses, ``numba:compile`` events) are counted by
    kernel; the first one logs :data:`COMPILING` and starts a progress display (rich, on
    stderr) when ``show``. Yields the Counter of compilations by kernel name."""
    from numba.core import event

    compiled: Counter[str] = Counter()
    ours = {id(d) for d in kernel_dispatchers()}
    total = max(len(ours), 1)
    display: list = []

    class _Listener(event.Listener):
        def on_start(self, ev) -> None:
            if not display:
                log.info("%s …", COMPILING)
                display.append(_start_display(show, total))

        def on_end(self, ev) -> None:
            disp = ev.data["dispatcher"]
            if id(disp) not in ours:  # numba's own helpers compiled on the way
                return
            compiled[disp.py_func.__qualname__] += 1
            bar = display[0] if display else None
            if bar is not None:
                bar.update(bar.task_ids[0], completed=min(len(compiled), total))

    try:
        with event.install_listener("numba:compile", _Listener()):
            yield compiled
    finally:
        if display and display[0] is not None:
            display[0].update(display[0].task_ids[0], completed=total)
            display[0].stop()


def _start_display(show: bool, total: int):
    """A started rich progress bar of ``total`` kernels on stderr, or None."""
    if not show:
        return None
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )
    from skyfuse.services.runtime.progress import stderr_console

    bar = Progress(
        SpinnerColumn(), TextColumn(COMPILING), BarColumn(), MofNCompleteColumn(),
        TimeElapsedColumn(), console=stderr_console, transient=False,
    )  # fmt: skip
    bar.add_task(COMPILING, total=total)
    bar.start()
    return bar


def kernel_dispatchers() -> list:
    """The compiled (numba, ``cache=True``) kernels of ``skyfuse.fusion`` loaded so far
    (after importing ``kernel_warmup``: every kernel it loads)."""
    import numba.core.registry
    import skyfuse.fusion.tracker.kernel_warmup  # noqa: F401  (imports the kernels)

    found = {}
    for name, mod in list(sys.modules.items()):
        if not name.startswith("skyfuse.fusion.") or mod is None:
            continue
        for obj in vars(mod).values():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj._cache is not None:
                found[id(obj)] = obj
    return list(found.values())


def cache_places() -> dict[str, Path]:
    """Where the kernels are cached: {what (NUMBA_CACHE_DIR, the package directory, the
    user cache directory): a directory}; several package directories are summarised by
    their common parent."""
    places: dict[str, list[Path]] = {}
    for d in kernel_dispatchers():
        cache = getattr(d, "_cache", None)
        impl = getattr(cache, "_impl", None)
        if impl is None:
            continue
        kind = LOCATORS.get(type(impl.locator).__name__, type(impl.locator).__name__)
        places.setdefault(kind, []).append(Path(cache.cache_path))
    out = {}
    for kind, paths in places.items():
        common = Path(*_common_parts(paths))
        out[kind] = common
    return out


def _common_parts(paths: list[Path]) -> tuple[str, ...]:
    parts = paths[0].parts
    for p in paths[1:]:
        n = 0
        while n < min(len(parts), len(p.parts)) and parts[n] == p.parts[n]:
            n += 1
        parts = parts[:n]
    return parts or ("/",)


def timed_load(logger: logging.Logger) -> float:
    """:func:`load_kernels` for a service: logs ``tracker kernels loaded in … s``."""
    t0 = time.perf_counter()
    load_kernels()
    seconds = time.perf_counter() - t0
    logger.info("tracker kernels loaded in %.2f s", seconds)
    return seconds
