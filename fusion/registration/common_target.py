"""Common-target residuals: pairs of plots of one track from two different radars.

For a plot of radar A at (corrected) time t_A on track T, converted to the system plane
as z_A with the correction β̂_A applied (β = (b_ψ, b_D, g, b_t), :mod:`fusion.frames.
sensor_bias`), the linearised bias model is (Fischer, Muehe & Cameron 1980, §3; Okello &
Ristic 2003, eq. 3-5)

    z_A = p_T(t_A) + H_A (β_A − β̂_A) + w_A,   H_A = [∂z/∂ψ, ∂z/∂D, D ∂z/∂D, −v_T]   (1)

(the time column: a clock offset b_t puts the plot at p_T(t_A − b_t) ≈ p_T(t_A) − v b_t).
With the most recent plot of another radar B on the same track, at t_B within
``max_pair_dt``, aligned to t_A with the track velocity v_T, the pair residual is

    y = z_A − z_B − v_T (t_A − t_B) + H_A β̂_A − H_B β̂_B = H_A β_A − H_B β_B + w       (2)
    W = R_A + R_B + Δt² P_vv + q |Δt|³/3 I                                          (3)

(Δt = t_A − t_B; P_vv the track's velocity covariance; the last term the white-
acceleration motion over Δt: Bar-Shalom, Li and Kirubarajan 2001, eq. 6.2.2-12). The
target position cancels, so (2) is linear in the biases alone: the measurement of the
registration filter. Every plot enters at most one pair (both plots of a pair are
consumed), so the residuals of different pairs share no plot noise. Horizontal (x, y)
components only.

The buffer of plots awaiting a partner is a set of NumPy columns bounded by
``capacity``; plots older than ``max_pair_dt`` are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.schemas.snapshot import array_field, entry

from .pairing_kernel import pair_residuals, partner_rows


class PlotColumns:
    """Plots of tracks (arrays over k plots): track id, radar index, time ns, horizontal
    position z (k, 2) m, covariance R (k, 2, 2) m², bias sensitivity H (k, 2, 4), the
    correction applied β̂ (k, 4), track velocity v (k, 2) m/s and its covariance
    P_vv (k, 2, 2).

    Stored packed, one row per plot: the integers (track, radar, time) in ``ints``
    (k, 3) and the 24 reals (z, R, H, β̂, v, P_vv, flattened in that order) in ``floats``
    (k, 24), so that selecting or appending plots is two array operations, not nine;
    the named columns are views of these."""

    def __init__(self, track, radar, time, z, R, H, applied, v, Pvv) -> None:
        k = len(track)
        self.ints = np.empty((k, 3), np.int64)
        self.ints[:, 0], self.ints[:, 1], self.ints[:, 2] = track, radar, time
        self.floats = np.empty((k, _WIDTH))
        for (lo, hi), col in zip(_SLICES, (z, R, H, applied, v, Pvv), strict=True):
            self.floats[:, lo:hi] = np.reshape(col, (k, hi - lo))

    @classmethod
    def _packed(cls, ints: np.ndarray, floats: np.ndarray) -> PlotColumns:
        out = cls.__new__(cls)
        out.ints, out.floats = ints, floats
        return out

    def _real(self, i: int, shape: tuple[int, ...]) -> np.ndarray:
        lo, hi = _SLICES[i]
        return self.floats[:, lo:hi].reshape((len(self.floats), *shape))

    track = property(lambda self: self.ints[:, 0])
    radar = property(lambda self: self.ints[:, 1])
    time = property(lambda self: self.ints[:, 2])
    z = property(lambda self: self._real(0, (2,)))
    R = property(lambda self: self._real(1, (2, 2)))
    H = property(lambda self: self._real(2, (2, 4)))
    applied = property(lambda self: self._real(3, (4,)))
    v = property(lambda self: self._real(4, (2,)))
    Pvv = property(lambda self: self._real(5, (2, 2)))

    def __len__(self) -> int:
        return len(self.ints)

    @classmethod
    def empty(cls) -> PlotColumns:
        return cls._packed(np.zeros((0, 3), np.int64), np.zeros((0, _WIDTH)))

    def take(self, idx) -> PlotColumns:
        return PlotColumns._packed(self.ints[idx], self.floats[idx])

    @staticmethod
    def concat(a: PlotColumns, b: PlotColumns) -> PlotColumns:
        return PlotColumns._packed(
            np.concatenate([a.ints, b.ints]), np.concatenate([a.floats, b.floats])
        )


_SIZES = (2, 4, 8, 4, 2, 4)  # z, R, H, applied, v, Pvv
_SLICES = tuple(zip(np.cumsum((0, *_SIZES[:-1])).tolist(), np.cumsum(_SIZES).tolist()))
_WIDTH = sum(_SIZES)


@dataclass
class ResidualPairs:
    """Pair residuals (eq. 2-3): y (k, 2), W (k, 2, 2), H_A, H_B (k, 2, 4), radar
    indices a, b (k,), and the pairs' times (k,) ns."""

    y: np.ndarray
    W: np.ndarray
    HA: np.ndarray
    HB: np.ndarray
    a: np.ndarray
    b: np.ndarray
    time: np.ndarray

    def __len__(self) -> int:
        return len(self.y)


def _found_in(keys: np.ndarray, of: np.ndarray) -> np.ndarray:
    """(n,) bool: which ``keys`` (int64) are among ``of`` — one sort of the few new keys
    and a binary search (np.isin costs ≈ 7× more at a batch's sizes)."""
    if len(of) == 0 or len(keys) == 0:
        return np.zeros(len(keys), bool)
    ordered = np.sort(of)
    i = np.minimum(np.searchsorted(ordered, keys), len(ordered) - 1)
    return ordered[i] == keys


class PairBuffer:
    """Plots awaiting a partner from another radar, and the pairing of eq. (2)."""

    def __init__(self, max_pair_dt: float, q: float, capacity: int) -> None:
        self.max_dt_ns = int(max_pair_dt * 1e9)
        self.q = float(q)
        self.capacity = int(capacity)
        self.store = PlotColumns.empty()
        self.dropped = 0

    def add(self, new: PlotColumns) -> ResidualPairs:
        """Pair the new plots (one radar's batch) with stored plots of other radars;
        store the unpaired ones; return the residuals of the pairs."""
        t_now = int(new.time.max()) if len(new) else None
        if t_now is not None:
            self._expire(t_now)
        s = self.store
        ia, ib = self._partners(new, s)
        pairs = self._residuals(new.take(ia), s.take(ib))
        keep_store = np.ones(len(s), bool)
        keep_store[ib] = False
        # a newer plot of the same (track, radar) replaces the stored one
        unpaired = np.ones(len(new), bool)
        unpaired[ia] = False
        rest = new.take(unpaired)
        keep_store &= ~_found_in(s.track * 64 + s.radar, rest.track * 64 + rest.radar)
        self.store = PlotColumns.concat(s.take(np.flatnonzero(keep_store)), rest)
        if len(self.store) > self.capacity:
            n_drop = len(self.store) - self.capacity
            self.dropped += n_drop
            self.store = self.store.take(np.arange(n_drop, len(self.store)))
        return pairs

    def to_snapshot(self) -> dict:
        """The plots awaiting a partner (packed: ``ints`` (k, 3), ``floats`` (k, 24), see
        :class:`PlotColumns`) and the count of plots dropped; the bounds are the
        configuration's."""
        return {"ints": self.store.ints, "floats": self.store.floats, "dropped": self.dropped}

    def from_snapshot(self, snap: dict) -> None:
        ints = array_field(snap, "ints", np.int64, (None, 3))
        floats = array_field(snap, "floats", np.float64, (len(ints), _WIDTH))
        dropped = entry(snap, "dropped", int)
        self.store, self.dropped = PlotColumns._packed(ints, floats), dropped

    def _partners(self, new: PlotColumns, s: PlotColumns) -> tuple[np.ndarray, np.ndarray]:
        """Rows (ia of ``new``, ib of ``s``) of the pairs: each new plot takes the stored
        plot of the same track from another radar nearest in time (within max_pair_dt;
        ties: the older stored row), and a stored plot partners at most one new plot (the
        nearest in time; ties: the first new row). The candidates are the stored rows of
        the same track, found by binary search on the store sorted by track (a few per
        plot: at most one per radar), not a new × store table."""
        # any sort: the kernel's choice within a track's rows does not depend on their order
        order = np.argsort(s.track)
        st = s.track[order]
        lo = np.searchsorted(st, new.track, "left")
        hi = np.searchsorted(st, new.track, "right")
        c = np.ascontiguousarray
        return partner_rows(order, lo, hi, c(new.radar), c(new.time), c(s.radar), c(s.time),
                            self.max_dt_ns)  # fmt: skip

    def _expire(self, t_now: int) -> None:
        fresh = np.flatnonzero(t_now - self.store.time <= self.max_dt_ns)
        if len(fresh) < len(self.store):
            self.store = self.store.take(fresh)

    def _residuals(self, A: PlotColumns, B: PlotColumns) -> ResidualPairs:
        c = np.ascontiguousarray
        y, W = pair_residuals(
            c(A.time), c(B.time), c(A.z), c(B.z), c(A.v), c(A.H), c(B.H), c(A.applied),
            c(B.applied), c(A.R), c(B.R), c(A.Pvv), self.q,
        )  # fmt: skip
        return ResidualPairs(y, W, A.H, B.H, A.radar, B.radar, A.time.copy())
