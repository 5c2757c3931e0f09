"""Columnar tables of declared columns: the tracker's track store and its smaller kin.

A :class:`Table` is a struct of NumPy arrays, one array per **declared column**
(:class:`Column`: name, dtype, the shape of one row, the value of a new row), in the spirit
of Stone Soup's declared properties but over all rows at once: no per-row Python object.
Columns come in :class:`ColumnGroup` s, one per owner, declared before the first row. One
:meth:`~Table.append`, one :meth:`~Table.keep` and one :meth:`~Table.take` serve every
column; a group may add hooks that run after them (``appended``, ``kept``) for state that
is not one row per track, such as a density's mixture components.

**The track store** (``Tracker.tracks``) has one row per live track, in the order the
tracks were started, and is the only place any part keeps per-track state:

* the tracker (:mod:`.tracker`): id, existence-chain state ([thesis] (5.3), (6.15-6.17)), times
  (last update, last plot, coast clock, birth), confirmation, counters, radar mask,
  height of the last plot;
* the track density (:mod:`.density`): its track-level estimate ``x``, ``P`` (the output
  layout, [thesis] (4.66-4.68)) and whatever else is one row per track (particle clouds and
  weights, [LM-IPF] eq. 3-4); a mixture density keeps its components (a variable number
  per track, [thesis] (5.12-5.15)) in its own component store, whose ``track`` column is kept
  in step with the rows by the density's ``appended`` / ``kept`` hooks, never by hand;
* the IMM density's reachability gate (:mod:`.density.reach_gate`): the last fix;
* the out-of-sequence update (:mod:`.oosm_pass`): the prior of each track's last
  ordinary update, per mode (Bar-Shalom 2002, A1);
* the re-identification (:mod:`.reidentification`): each track's last informative fix.

A part declares its group when it is configured (the gate only when it is on, the
out-of-sequence memory only for a density that retrodicts, …), so adding per-track state
is one more group: no list of arrays to extend elsewhere.

**Tables keyed by something else** are their own tables, each with one owner: the
terminated tracks awaiting re-identification (:class:`~.reidentification.TerminatedTracks`,
one row per terminated track, found by its former id) and the plots awaiting a two-point
partner (:class:`~.initiation.PlotBuffer`, one row per plot). They are not row-aligned with
the tracks (their rows outlive tracks or are not tracks), so they are not groups of the
track store; they use the same :class:`Table`.

**Snapshots** (:meth:`~Table.to_snapshot`, :meth:`~Table.from_snapshot`) are the declared
columns by name, read back only if every column is there with its declared dtype and row
shape and no other column is: the declaration is the format (:mod:`schemas.snapshot`).

Storage: every column is an array with spare rows (capacity grows by doubling), of which
the first ``len(table)`` are the rows; ``table.name`` is a view of those rows. Appending
writes into the spare rows (amortised in the rows appended, not the rows held); keeping
gathers the kept rows to the front of the same arrays. So a view of a column is valid
until the next :meth:`~Table.keep` (take a copy to keep rows longer: the tracker's
outputs do). Write a column in place (``table.height[rows] = …``, ``table.height[:] =
…``); assigning a column is refused.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from skyfuse.schemas.snapshot import SnapshotError, array_field, mapping

_MIN_CAPACITY = 64


@dataclass(frozen=True)
class Column:
    """A declared column: ``name``, ``dtype``, ``shape`` of one row (``()`` for a
    scalar per row) and ``fill``, the value of a new row that no one gives (``None``: it
    must be given, or computed by its group's ``init``)."""

    name: str
    dtype: type | str
    shape: tuple[int, ...] = ()
    fill: float | int | bool | None = None
    doc: str = ""


@dataclass(frozen=True)
class NewTracks:
    """Tracks to start: their Gaussian initial states x (n, d), P (n, d, d) in the output
    layout (CV [x, vx, y, vy(, z, vz)], m and m/s) and their times t (n,) ns (None for a
    store without the tracker's columns, e.g. a density on its own)."""

    x: np.ndarray
    P: np.ndarray
    t: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.x)


@dataclass
class ColumnGroup:
    """The columns of one owner. ``init(new) -> {column: values}`` computes the new rows'
    values of columns without a fill from what :meth:`Table.append` was given (``new``,
    e.g. :class:`NewTracks`); ``appended(rows, new)`` runs after the rows are written,
    ``kept(mask)`` after :meth:`Table.keep` (hooks of state that is not one row each).
    Give module-level functions or bound methods (a tracker is pickled by the Monte Carlo
    evaluation's workers; a lambda is not picklable)."""

    owner: str
    columns: tuple[Column, ...]
    init: Callable | None = None
    appended: Callable | None = None
    kept: Callable | None = None
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        self.names = tuple(c.name for c in self.columns)


class Table:
    """Rows of declared columns (see the module docstring)."""

    def __init__(self, *groups: ColumnGroup) -> None:
        object.__setattr__(self, "_groups", [])
        object.__setattr__(self, "_columns", {})
        object.__setattr__(self, "_buffers", {})
        object.__setattr__(self, "_n", 0)
        for g in groups:
            self.declare(g)

    def __setattr__(self, name: str, value) -> None:
        if name in self._columns:
            raise AttributeError(f"column {name!r}: write into it ({name}[...] = ...)")
        object.__setattr__(self, name, value)

    def __getstate__(self) -> dict:
        """Pickled without the column views (a copied view would no longer write into
        its buffer); :meth:`__setstate__` makes them again."""
        return {k: v for k, v in self.__dict__.items() if k not in self._columns}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._views()

    # ---------------------------------------------------------------- declaration
    def declare(self, group: ColumnGroup) -> None:
        """Add a group of columns (before the first row)."""
        if self._n:
            raise ValueError(f"{group.owner}: columns are declared before the first row")
        for c in group.columns:
            if c.name in self._columns or hasattr(type(self), c.name) or c.name.startswith("_"):
                raise ValueError(f"{group.owner}: column name {c.name!r} is taken")
        self._groups.append(group)
        cap = len(next(iter(self._buffers.values()), ())) or _MIN_CAPACITY
        for c in group.columns:
            self._columns[c.name] = c
            self._buffers[c.name] = np.zeros((cap, *c.shape), np.dtype(c.dtype))
        self._views()

    @property
    def names(self) -> tuple[str, ...]:
        """The columns, in declaration order."""
        return tuple(self._columns)

    def column(self, name: str) -> Column:
        return self._columns[name]

    def groups(self) -> tuple[ColumnGroup, ...]:
        return tuple(self._groups)

    def __len__(self) -> int:
        return self._n

    def _views(self) -> None:
        n, d = self._n, self.__dict__
        for name, buf in self._buffers.items():
            d[name] = buf[:n]

    # ---------------------------------------------------------------- rows
    def append(self, new=None, **values) -> np.ndarray:
        """Append rows: columns given in ``values`` take them, the others their group's
        ``init(new)`` or their fill; returns the new rows' indices. ``new`` (e.g.
        :class:`NewTracks`) is what the groups' ``init`` and ``appended`` receive."""
        k = len(new) if new is not None else len(next(iter(values.values()), ()))
        lo = self._n
        if k == 0:
            return np.arange(lo, lo)
        groups = self._groups
        if new is not None:
            for g in groups:
                if g.init is not None:
                    for name, v in g.init(new).items():
                        values.setdefault(name, v)
        hi = lo + k
        self._reserve(hi)
        buffers = self._buffers
        for name, c in self._columns.items():
            v = values.get(name)
            if v is None:
                if c.fill is None:
                    raise ValueError(f"column {name!r}: no value for the new rows")
                v = c.fill
            elif (v.shape if isinstance(v, np.ndarray) else np.shape(v)) != (k, *c.shape):
                raise ValueError(f"column {name!r}: {np.shape(v)} for {k} rows of {c.shape}")
            buffers[name][lo:hi] = v
        object.__setattr__(self, "_n", hi)
        self._views()
        rows = np.arange(lo, hi)
        for g in groups:
            if g.appended is not None:
                g.appended(rows, new)
        return rows

    def _reserve(self, n: int) -> None:
        cap = len(next(iter(self._buffers.values()), ()))
        if n <= cap:
            return
        cap = max(2 * cap, n, _MIN_CAPACITY)
        for name, buf in self._buffers.items():
            grown = np.empty((cap, *buf.shape[1:]), buf.dtype)
            grown[: self._n] = buf[: self._n]
            self._buffers[name] = grown

    def keep(self, mask: np.ndarray) -> None:
        """Keep the rows where ``mask`` (len(self),) is True, in order, gathered to the
        front of the arrays (views taken before are stale); then the groups' ``kept``
        hooks. Rows before the first dropped one stay where they are."""
        mask = np.asarray(mask, bool)
        drop = np.flatnonzero(~mask)
        n = self._n
        k = n - len(drop)
        if len(drop) == 1:  # one row: the rows after it move up by one
            a = int(drop[0])
            for buf in self._buffers.values():
                buf[a:k] = buf[a + 1 : n]
        elif len(drop):
            a = int(drop[0])
            idx = np.flatnonzero(mask[a:]) + a
            for buf in self._buffers.values():
                buf[a:k] = buf[:n].take(idx, axis=0)  # in place: the capacity stays
        object.__setattr__(self, "_n", k)
        self._views()
        for g in self._groups:
            if g.kept is not None:
                g.kept(mask)

    def take(self, rows, names: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
        """Copies of the rows ``rows`` of the columns ``names`` (default: all)."""
        return {k: getattr(self, k)[rows] for k in (names or self._columns)}

    # ---------------------------------------------------------------- snapshots
    def to_snapshot(self) -> dict:
        """``{"rows": n, "columns": {name: array}}``: the rows of every declared column
        (views: serialise before the table changes)."""
        return {"rows": self._n, "columns": {k: getattr(self, k) for k in self._columns}}

    def from_snapshot(self, snap) -> None:
        """Hold the rows of a snapshot of a table with the same declaration; a column
        missing, extra or of another dtype or row shape is a :class:`SnapshotError` (and
        nothing changes). The groups' hooks do not run: their owners restore their own
        state (and check it against ``len(self)``)."""
        snap = mapping(snap, "table")
        n = snap.get("rows")
        if type(n) is not int or n < 0:
            raise SnapshotError(f"table rows {n!r}")
        cols = mapping(snap.get("columns"), "table columns")
        extra = sorted(set(cols) - set(self._columns))
        if extra:
            raise SnapshotError(f"undeclared column {extra[0]!r}")
        data = {}
        for name, c in self._columns.items():
            data[name] = array_field(cols, name, np.dtype(c.dtype), (n, *c.shape))
        cap = max(_MIN_CAPACITY, 2 * n)
        for name, a in data.items():
            buf = np.empty((cap, *a.shape[1:]), a.dtype)
            buf[:n] = a
            self._buffers[name] = buf
        object.__setattr__(self, "_n", n)
        self._views()


def store_for(*parts) -> Table:
    """A track store with the columns of ``parts`` only (each part's ``attach`` is
    called): a density used on its own, outside a tracker (tests, benchmarks)."""
    table = Table()
    for part in parts:
        part.attach(table)
    return table
