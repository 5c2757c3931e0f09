"""``skyfuse warmup`` against numba's own cache rules, on a copy of the package mounted
read-only (a private mount namespace, ``unshare -m``: root ignores file permissions, not a
read-only mount): numba takes ``NUMBA_CACHE_DIR`` when it can write there, else the
package's ``__pycache__`` when writable, else the user's cache directory, and never reads
a cache it cannot write. Expected: the first run compiles and says so, a later run in the
fallback user cache loads everything, an unwritable ``NUMBA_CACHE_DIR`` is reported as
ignored, and with no writable place at all the command exits 1 with the remedy.

The first run's cache is seeded with the kernels this checkout has already compiled (the
suite's own ``__pycache__``, relocated where numba looks for the copy's: same file names,
same source stamps), all but those of :data:`COLD`, so the first run compiles only those
(the cold-cache path, ≈ 3 s) instead of every kernel again (≈ 65 s of CPU). Where the
seeding does not apply (no in-tree cache, another numba layout) the first run compiles
everything, as before."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
PACKAGES = ("fusion", "schemas", "services")
COLD = "cholesky_kernels"
"""The module whose kernels the first run must compile (not seeded)."""


def _can_mount_read_only() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = "mount --bind /tmp /tmp && mount -o remount,bind,ro /tmp"
    r = subprocess.run(["unshare", "-m", "sh", "-c", probe], capture_output=True)
    return r.returncode == 0


@pytest.fixture(scope="module")
def install(tmp_path_factory) -> Path:
    """A copy of the package tree as an installed ``skyfuse`` (no caches in it)."""
    root = tmp_path_factory.mktemp("install")
    for name in PACKAGES:
        shutil.copytree(
            ROOT / name, root / "skyfuse" / name, ignore=shutil.ignore_patterns("__pycache__")
        )
    return root


def seed_cache(install: Path, cache: Path) -> None:
    """Copy this checkout's compiled kernels (``fusion/**/__pycache__``, after loading them
    here) into ``cache`` where numba's ``NUMBA_CACHE_DIR`` locator looks for the kernels of
    ``install`` (the copy keeps the sources' mtimes: the index stamps match), except
    :data:`COLD`'s."""
    from numba.core.caching import _CacheLocator
    from skyfuse.fusion.tracker.kernel_warmup import warm_up

    warm_up()  # the in-tree cache, as any test that tracks makes it
    for pycache in (ROOT / "fusion").rglob("__pycache__"):
        rel = pycache.parent.relative_to(ROOT)
        sub = _CacheLocator.get_suitable_cache_subpath(str(install / "skyfuse" / rel / "x.py"))
        for f in pycache.iterdir():
            if f.suffix in (".nbi", ".nbc") and not f.name.startswith(f"{COLD}."):
                (cache / sub).mkdir(parents=True, exist_ok=True)
                shutil.copy2(f, cache / sub / f.name)


def warmup(install: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    """``skyfuse warmup`` from the read-only copy ``install``, with ``env`` added."""
    full = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    full |= {"PYTHONPATH": str(install), **env}
    cmd = f"{sys.executable} -m skyfuse.services.cli.main warmup"
    script = f"mount --bind {install} {install} && mount -o remount,bind,ro {install} && {cmd}"
    return subprocess.run(
        ["unshare", "-m", "sh", "-c", script],
        capture_output=True, text=True, env=full, cwd=install.parent, timeout=600,
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.skipif(not _can_mount_read_only(), reason="no private read-only mount here")
def test_warmup_caches_where_numba_can_write_and_says_where(install, tmp_path):
    cache, home = tmp_path / "numba-cache", tmp_path / "home"
    home.mkdir()
    seed_cache(install, cache)
    first = warmup(install, {"NUMBA_CACHE_DIR": str(cache), "XDG_CACHE_HOME": str(home)})
    assert first.returncode == 0, first.stderr[-2000:]
    assert "compiling tracker kernels (first run only)" in first.stderr
    assert f"kernel cache: {cache} — NUMBA_CACHE_DIR" in first.stdout
    assert (
        "compiled" in first.stdout and not (install / "skyfuse" / "fusion" / "__pycache__").exists()
    )
    assert list(cache.rglob(f"{COLD}.*.nbi")) and not list(home.rglob("*.nbi"))

    # the same install read-only without NUMBA_CACHE_DIR: numba's user-wide directory (its
    # layout is the same as NUMBA_CACHE_DIR's, so the cache made above is found there)
    shutil.copytree(cache, home / "numba")
    again = warmup(install, {"XDG_CACHE_HOME": str(home)})
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"kernel cache: {home / 'numba'} — the user's cache directory" in again.stdout
    assert "package directory is read-only" in again.stdout
    assert "loaded from the cache" in again.stdout and "compiling" not in again.stderr

    ignored = warmup(install, {"NUMBA_CACHE_DIR": "/dev/null/x", "XDG_CACHE_HOME": str(home)})
    assert ignored.returncode == 0, ignored.stderr[-2000:]
    assert "NUMBA_CACHE_DIR=/dev/null/x is not writable: numba ignored it" in ignored.stderr
    assert "loaded from the cache" in ignored.stdout


@pytest.mark.skipif(not _can_mount_read_only(), reason="no private read-only mount here")
def test_warmup_without_any_writable_cache_exits_1_with_the_remedy(install):
    # a read-only package, NUMBA_CACHE_DIR unset and a user cache below a file
    r = warmup(install, {"XDG_CACHE_HOME": "/dev/null/cache", "HOME": "/dev/null"})
    assert r.returncode == 1, (r.stdout, r.stderr[-2000:])
    assert "the compiled kernels cannot be cached" in r.stderr
    assert "set NUMBA_CACHE_DIR to a directory this user can write" in r.stderr
