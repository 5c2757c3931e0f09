"""Snapshots of state: the vocabulary every owner of state uses to write and read it.

Part of the wire contract: the fusion service's state is saved to disk and published on
``fusion/{id}/state`` (:mod:`schemas.keys`) in this vocabulary. An owner of state (the
track store and the parts of a tracker, the registration estimator, and in
``skyfuse.services`` the track feed, the reorder buffer …) writes its state with
``to_snapshot()`` as a tree of plain values: ``dict`` with ``str`` keys, ``list``,
``str``, ``int``, ``float``, ``bool``, ``None`` and NumPy arrays of numbers; and reads it
back with ``from_snapshot(snapshot)``, into an object freshly constructed with the
configuration the snapshot was made with. The names and shapes are the owner's
declaration, so a snapshot never depends on private attribute names, and nothing in it
is a type to rebuild: the container (``skyfuse.services.fusion.state_codec``) only has
to carry numbers, strings and arrays.

Reading checks every value against the declaration with the helpers below and raises
:class:`SnapshotError` (a ``ValueError``) naming what is wrong; an owner checks
everything before it changes anything, or is discarded by its caller on an error, so a
state is never half restored. :func:`check_version` refuses a snapshot of another
version with a message that names both.
"""

from __future__ import annotations

import numpy as np

_NUMERIC_KINDS = "biuf"


class SnapshotError(ValueError):
    """A snapshot that does not fit the declaration it is read with."""


def check_version(snap, kind: str, version: int) -> dict:
    """``snap`` as a dict if its ``version`` is ``version``; else a :class:`SnapshotError`
    naming both versions (``kind``: what the snapshot is, for the message)."""
    snap = mapping(snap, kind)
    found = snap.get("version")
    if found != version:
        raise SnapshotError(
            f"{kind} snapshot version {found!r}: this version of skyfuse reads version "
            f"{version} only"
        )
    return snap


def mapping(value, what: str) -> dict:
    """``value`` if it is a dict with str keys, else a :class:`SnapshotError`."""
    if type(value) is not dict or not all(type(k) is str for k in value):
        raise SnapshotError(f"{what}: not a mapping")
    return value


def entry(snap: dict, name: str, kind: type | tuple[type, ...]):
    """``snap[name]`` if it is of exactly ``kind`` (``int`` is not a ``bool`` here; a
    ``float`` field also takes an ``int``)."""
    kinds = kind if isinstance(kind, tuple) else (kind,)
    value = snap.get(name)
    if float in kinds and type(value) is int:
        return float(value)
    if type(value) not in kinds:
        names = "/".join(k.__name__ for k in kinds)
        raise SnapshotError(f"{name}: {type(value).__name__} where {names} is declared")
    return value


def integers(snap: dict, name: str) -> list[int]:
    """``snap[name]`` if it is a list of ints."""
    value = entry(snap, name, list)
    if not all(type(v) is int for v in value):
        raise SnapshotError(f"{name}: not a list of integers")
    return value


def strings(snap: dict, name: str) -> list[str]:
    """``snap[name]`` if it is a list of str."""
    value = entry(snap, name, list)
    if not all(type(v) is str for v in value):
        raise SnapshotError(f"{name}: not a list of strings")
    return value


def counts(snap: dict, name: str) -> dict[str, int]:
    """``snap[name]`` if it is a dict of str → int (counters)."""
    value = mapping(snap.get(name), name)
    if not all(type(v) is int for v in value.values()):
        raise SnapshotError(f"{name}: not a table of counts")
    return value


def array_field(snap: dict, name: str, dtype, shape: tuple) -> np.ndarray:
    """``snap[name]`` if it is an array of ``dtype`` and ``shape`` (``None`` in ``shape``:
    any length on that axis)."""
    a = snap.get(name)
    if type(a) is not np.ndarray:
        raise SnapshotError(f"{name}: {type(a).__name__} where an array is declared")
    want = np.dtype(dtype)
    if a.dtype != want or a.dtype.kind not in _NUMERIC_KINDS:
        raise SnapshotError(f"{name}: dtype {a.dtype}, declared {want}")
    if len(a.shape) != len(shape) or any(s is not None and s != d for s, d in zip(shape, a.shape)):
        declared = tuple("*" if s is None else s for s in shape)
        raise SnapshotError(f"{name}: shape {a.shape}, declared {declared}")
    return a
