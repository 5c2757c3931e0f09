"""Small state files of the services, written atomically, and where they live.

:func:`atomic_write`: a temporary file in the same directory, ``fsync``, ``os.replace``
over the old file, ``fsync`` of the directory — after ``kill -9`` or a power loss the
file is the previous or the new content, never a torn one. :func:`state_home`: the
per-user state directory ``$XDG_STATE_HOME/skyfuse`` (default ``~/.local/state/skyfuse``)
under which each service keeps its own directory (``fusion-{id}``, ``sensor-{radar}``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def state_home() -> Path:
    """``$XDG_STATE_HOME/skyfuse`` (default ``~/.local/state/skyfuse``)."""
    base = os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state"
    return Path(base) / "skyfuse"


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file, fsync, replace, fsync dir)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    dfd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dfd)
    finally:
        os.close(dfd)
