"""``skyfuse warmup``: compile the tracker's numba kernels into their on-disk cache now,
once per installed version, instead of at a user's first run (about 20 s on a 2-core
machine; loading them from the cache takes a fraction of a second). The README's install
command and the Docker image run it; ``skyfuse fusion`` and ``skyfuse demo`` load the
kernels the same way (:mod:`skyfuse.services.fusion.kernel_cache`, which says where the
cache is), so if the cache is cold they say so and show progress.

Exit codes: 0 the kernels are compiled and cached, 1 they cannot be cached."""

from __future__ import annotations

import argparse
import os
import sys

from skyfuse.services.fusion.kernel_cache import LOCATORS, cache_places, load_kernels
from skyfuse.services.runtime.lifecycle import EXIT_FAILED, EXIT_OK


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "warmup",
        help="compile the tracker's kernels into their cache (run once after installing)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="progress display while compiling (default: on a terminal only)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        seconds, compiled = load_kernels(progress=args.progress)
    except RuntimeError as e:  # numba: "cannot cache function ...: no locator available"
        print(f"skyfuse warmup: the compiled kernels cannot be cached: {e}", file=sys.stderr)
        print("  set NUMBA_CACHE_DIR to a directory this user can write", file=sys.stderr)
        return EXIT_FAILED
    places = cache_places()
    for where, path in places.items():
        print(f"kernel cache: {path} — {where}")
    asked = os.environ.get("NUMBA_CACHE_DIR")
    if asked and LOCATORS["UserProvidedCacheLocator"] not in places:
        print(f"NUMBA_CACHE_DIR={asked} is not writable: numba ignored it", file=sys.stderr)
    done = f"compiled {compiled} kernels" if compiled else "loaded from the cache"
    print(f"tracker kernels ready in {seconds:.2f} s ({done})")
    return EXIT_OK
