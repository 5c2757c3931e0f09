"""The component store of a track density in slots: all components of all tracks (a
:class:`~.components.Mixture` or an IMM ``IMMComponents``: arrays, or lists of arrays,
with one row per component) held in arrays with spare capacity, so that a sector batch
costs work in proportion to the components it touches, not to the whole picture.

* **Append** (new tracks, the updated components of a batch): written into the next
  free slots; the arrays grow by doubling.
* **Replace** the components of some tracks (the update of a batch): their slots are
  marked dead (track −1), the new components appended.
* **Keep** a subset of the tracks (termination, duplicates): the other tracks' slots
  are marked dead and the live slots' track rows renumbered (integers only).
* **Compaction**: when the dead slots outnumber the live ones (and 1,024), the live
  slots are copied into new arrays, in slot order.

The live slots, in slot order, are exactly the components in the order the previous
store (take + concatenate after every operation) kept them: every sum over
components, and so every result, is the same to the last bit. Readers get copies
(:meth:`tracks`, :meth:`live`), or views of the used slots when they ask for all of
them and all are live; such views stay valid: arrays are written in place only past
the used slots, and the ``track`` column is replaced by a new array, never written,
when slots die or tracks are renumbered.
"""

from __future__ import annotations

from dataclasses import fields
from operator import attrgetter

import numba
import numpy as np
from skyfuse.schemas.snapshot import SnapshotError, array_field, mapping

_COMPACT_MIN = 1024


_LAYOUT: dict[type, tuple[tuple[str, ...], bool, object]] = {}


def _layout(comp) -> tuple[tuple[str, ...], bool, object]:
    """(field names, whether any field is a per-mode list, a getter of all fields)."""
    lay = _LAYOUT.get(type(comp))
    if lay is None:
        names = tuple(f.name for f in fields(comp))
        lists = any(isinstance(getattr(comp, n), list) for n in names)
        lay = _LAYOUT[type(comp)] = (names, lists, attrgetter(*names))
    return lay


def _fields(comp) -> tuple[str, ...]:
    return _layout(comp)[0]


def _arrays(comp) -> list[np.ndarray]:
    """The arrays of a components object, the per-mode lists flattened, in field order."""
    _, lists, get = _layout(comp)
    if not lists:
        return list(get(comp))
    out = []
    for v in get(comp):
        if isinstance(v, list):
            out.extend(v)
        else:
            out.append(v)
    return out


def _map(comp, fn):
    """A components object of the same type with ``fn`` applied to every array (also
    inside the per-mode lists)."""
    _, lists, get = _layout(comp)
    if not lists:
        return type(comp)(*[fn(v) for v in get(comp)])
    return type(comp)(*[[fn(a) for a in v] if isinstance(v, list) else fn(v) for v in get(comp)])


@numba.njit(cache=True, nogil=True)
def _row_slots(track, n, rows, ntracks):
    """(the used slots whose track is one of ``rows`` (sorted), in slot order, each one's
    index into ``rows``)."""
    pos = np.full(ntracks, -1, np.int64)
    for i in range(len(rows)):
        pos[rows[i]] = i
    count = 0
    for s in range(n):
        t = track[s]
        count += t >= 0 and pos[t] >= 0
    idx = np.empty(count, np.int64)
    loc = np.empty(count, np.int64)
    c = 0
    for s in range(n):
        t = track[s]
        if t >= 0 and pos[t] >= 0:
            idx[c] = s
            loc[c] = pos[t]
            c += 1
    return idx, loc


@numba.njit(cache=True, nogil=True)
def _renumbered(track, n, mask):
    """(a copy of ``track`` whose first n slots hold the new row of their track, −1 for a
    dropped track, the number of live slots)."""
    new_row = np.empty(len(mask), np.int64)
    r = 0
    for i in range(len(mask)):
        new_row[i] = r if mask[i] else -1
        r += mask[i]
    out = track.copy()
    alive = 0
    for s in range(n):
        t = track[s]
        out[s] = new_row[t] if t >= 0 else -1
        alive += out[s] >= 0
    return out, alive


def _int64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)


class ComponentSlots:
    """Slots of the components of a density (see the module docstring). ``empty``: a
    components object with 0 rows (gives the type, the per-mode layout and the dtypes)."""

    def __init__(self, empty, capacity: int = 64) -> None:
        self.n = 0
        self.alive = 0
        self.data = _map(empty, lambda a: np.zeros((capacity, *a.shape[1:]), a.dtype))
        self.data.track[:] = -1

    @classmethod
    def holding(cls, comp) -> ComponentSlots:
        """Slots holding the components ``comp`` (in their order)."""
        slots = cls(comp.take(np.zeros(0, np.int64)), max(64, len(comp)))
        slots.append(comp)
        return slots

    def __len__(self) -> int:
        return self.alive

    # ---------------------------------------------------------------- reading
    def _slots(self, inside: np.ndarray | None = None) -> np.ndarray:
        """Used slots that are live (and whose track is ``inside``), in slot order."""
        t = self.data.track[: self.n]
        if inside is None:
            return np.flatnonzero(t >= 0)
        return np.flatnonzero(np.append(np.asarray(inside, bool), False)[t])

    def live(self):
        """Every live component (a copy), in slot order."""
        return self.data.take(self._slots())

    def tracks(self, inside: np.ndarray):
        """The live components of the tracks where ``inside`` (n_tracks,) is True, in slot
        order: a copy, or read-only views when they are all the used slots."""
        n = self.n
        if self.alive == n and inside.all():  # every used slot, in order: no copy
            return _map(self.data, lambda a: a[:n])
        return self.data.take(self._slots(inside))

    # ---------------------------------------------------------------- writing
    def append(self, new) -> None:
        """Store the components ``new`` in the next free slots."""
        m = len(new)
        if m == 0:
            return
        lo, hi = self.n, self.n + m
        if hi > len(self.data.track):
            self._grow(new)
            return
        for d, s in zip(_arrays(self.data), _arrays(new)):
            d[lo:hi] = s
        self.n, self.alive = hi, self.alive + m

    def _grow(self, new) -> None:
        """New arrays with spare capacity holding the live slots, in order, then ``new``
        (empty ``new``: the compaction)."""
        keep = None if self.alive == self.n else self._slots()
        k = self.alive
        cap = max(2 * (k + len(new)), 64)

        def grown(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            out = np.empty((cap, *a.shape[1:]), a.dtype)
            if keep is None:
                out[:k] = a[:k]
            else:
                a.take(keep, axis=0, out=out[:k])
            out[k : k + len(b)] = b
            return out

        it = iter(_arrays(new))
        self.data = _map(self.data, lambda a: grown(a, next(it)))
        self.data.track[k + len(new) :] = -1
        self.n = self.alive = k + len(new)

    def replace(self, inside: np.ndarray, new) -> None:
        """The components of the tracks where ``inside`` are replaced by ``new``."""
        self.replace_rows(np.flatnonzero(inside), len(inside), new)

    def replace_rows(self, rows: np.ndarray, ntracks: int, new) -> None:
        """The components of the track rows ``rows`` (sorted, of ``ntracks``) are replaced
        by ``new``."""
        if self.alive == self.n and len(rows) == ntracks:  # every track: ``new`` is the store
            self.data, self.n, self.alive = new, len(new), len(new)
            return
        self._kill(_row_slots(self.data.track, self.n, _int64(rows), ntracks)[0])
        self.append(new)

    def keep(self, mask: np.ndarray) -> None:
        """Keep the tracks where ``mask`` (n_tracks,) is True, renumbered 0 … in order."""
        # a new track array: copies handed out stay valid
        self.data.track, self.alive = _renumbered(
            self.data.track, self.n, np.ascontiguousarray(mask, dtype=bool)
        )
        self._maybe_compact()

    def _kill(self, slots: np.ndarray) -> None:
        if len(slots):
            track = self.data.track.copy()
            track[slots] = -1
            self.data.track = track
            self.alive -= len(slots)

    def _maybe_compact(self) -> None:
        dead = self.n - self.alive
        if dead > max(self.alive, _COMPACT_MIN):
            self._grow(self.data.take(np.zeros(0, np.int64)))

    def rows(self, rows: np.ndarray, ntracks: int):
        """(the live components of the track rows ``rows`` (sorted) in slot order, each
        component's index into ``rows``): a copy, or views when they are every used slot
        (:meth:`tracks`); one compiled pass over the used slots (:func:`_row_slots`)."""
        idx, loc = _row_slots(self.data.track, self.n, _int64(rows), ntracks)
        n = self.n
        if self.alive == n and len(idx) == n:  # every used slot, in order: no copy
            return _map(self.data, lambda a: a[:n]), loc
        return self.data.take(idx), loc

    # ---------------------------------------------------------------- snapshots
    def to_snapshot(self) -> dict:
        """The live components, in slot order, as named columns (a per-mode list field
        ``x`` as ``x0``, ``x1``, …): ``{"rows": C, "columns": {name: array}}``."""
        comp = self.live()
        cols = {}
        for name in _fields(comp):
            v = getattr(comp, name)
            if isinstance(v, list):
                cols.update({f"{name}{j}": a for j, a in enumerate(v)})
            else:
                cols[name] = v
        return {"rows": len(comp), "columns": cols}

    @classmethod
    def from_snapshot(cls, snap, empty, ntracks: int) -> ComponentSlots:
        """Slots holding the components of :meth:`to_snapshot`, checked against
        ``empty`` (a components object with 0 rows: the columns, their dtypes and row
        shapes) and the ``ntracks`` track rows: every component belongs to a row, every
        row has a component, weights are finite and non-negative
        (:class:`~schemas.snapshot.SnapshotError` otherwise)."""
        snap = mapping(snap, "components")
        c = snap.get("rows")
        if type(c) is not int or c < 0:
            raise SnapshotError(f"components: rows {c!r}")
        cols = mapping(snap.get("columns"), "component columns")
        values, names = [], set()
        for name in _fields(empty):
            v = getattr(empty, name)
            per_mode = isinstance(v, list)
            keyed = [(f"{name}{j}", a) for j, a in enumerate(v)] if per_mode else [(name, v)]
            names.update(k for k, _ in keyed)
            got = [array_field(cols, k, a.dtype, (c, *a.shape[1:])) for k, a in keyed]
            values.append(got if per_mode else got[0])
        if set(cols) != names:
            raise SnapshotError(f"component columns {sorted(set(cols) - names)} not declared")
        comp = type(empty)(*values)
        counts = np.bincount(comp.track[comp.track >= 0], minlength=ntracks)
        if (comp.track < 0).any() or len(counts) > ntracks or (ntracks and counts.min() == 0):
            raise SnapshotError(f"components of {len(counts)} track rows for {ntracks} tracks")
        if not (np.isfinite(comp.w).all() and (comp.w >= 0).all()):
            raise SnapshotError("component weights not finite and non-negative")
        return cls.holding(comp)
