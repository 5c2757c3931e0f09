"""Track initiation from plots no existing track selected ([thesis] §3.5, §7.1).

* Two-point differencing (3.25-3.27): a plot z₁ kept from an earlier batch and a new plot
  z₂ with ‖z₂ − z₁‖ ≤ v_max Δt start a track (the formulas live in
  :mod:`fusion.filters.initiation`, the one initiation of skyfuse).
* One-point: x̂ = [z, 0] per axis, P = diag(R, v_max²/3).

Unused plots wait in a :class:`PlotBuffer` for ``max_dt`` seconds; a buffered plot that
forms pairs is consumed by them.
"""

from __future__ import annotations

import numba
import numpy as np
from skyfuse.fusion.association.gating_kernels import windows
from skyfuse.fusion.filters.initiation import one_point as initial_one_point
from skyfuse.fusion.filters.initiation import two_point

from .store import Column, ColumnGroup, Table

__all__ = ["PlotBuffer", "one_point", "pair_plots", "two_point"]


def one_point(z: np.ndarray, R: np.ndarray, v_max: float) -> tuple[np.ndarray, np.ndarray]:
    """One-point initial states: zero velocity with the variance v_max²/3 of a
    Uniform(−v_max, v_max) velocity (:func:`fusion.filters.initiation.one_point`)."""
    return initial_one_point(z, R, v_max**2 / 3.0)


class PlotBuffer(Table):
    """Plots not selected by any track, waiting for a two-point partner: a
    :class:`~.store.Table` of z (m, k), R (m, k, k), time (m,) ns and the plots' history
    ids uid (m,) (one row per plot, not per track: its own table)."""

    @classmethod
    def empty(cls, k: int) -> PlotBuffer:
        return cls(
            ColumnGroup(
                "plot buffer",
                (Column("z", np.float64, (k,), doc="position, system frame, m"),
                 Column("R", np.float64, (k, k), doc="its covariance, m²"),
                 Column("time", np.int64, doc="plot time, ns"),
                 Column("uid", np.int64, doc="plot history id")),
            )
        )  # fmt: skip

    def add(self, z: np.ndarray, R: np.ndarray, time: np.ndarray, uid: np.ndarray) -> None:
        self.append(z=z, R=R, time=time, uid=uid)


def pair_plots(
    buffer: PlotBuffer,
    z: np.ndarray,
    time: np.ndarray,
    v_max: float,
    min_dt: float,
    max_dt: float,
    now_ns: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (buffer index, new plot index, Δt s) with min_dt ≤ Δt ≤ max_dt and
    ‖z₂ − z₁‖ ≤ v_max Δt (the maximum-velocity criterion of [thesis] §7.1), and the
    buffered plots that stay (not expired, not paired): a buffered plot expires when it is
    more than ``max_dt`` s older than ``now_ns`` (None: none expires). One compiled pass
    (:func:`_pairs`): the box |Δ| ≤ v_max max_dt around each new plot (the gating's
    windows), then the exact tests; pairs in the order of the new plots, then of the
    buffer's sorted first coordinate."""
    n = len(buffer)
    if n == 0 or len(z) == 0:
        e = np.zeros(0, np.int64)
        stay = np.ones(n, bool) if now_ns is None else (now_ns - buffer.time) * 1e-9 <= max_dt
        return e, e, np.zeros(0), stay
    c = np.ascontiguousarray
    return _pairs(c(buffer.z), c(buffer.time), -1 if now_ns is None else int(now_ns),
                  c(z, dtype=np.float64), c(time, dtype=np.int64), float(v_max),
                  float(min_dt), float(max_dt))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _pairs(bz, bt, now, z, t, v_max, min_dt, max_dt):
    """The loops of :func:`pair_plots` (``now`` < 0: no expiry): the windows of the
    gating's pre-gate (:func:`~fusion.association.gating_kernels.windows`), then the
    expiry, the Δt and the distance tests."""
    alive = np.empty(len(bt), np.bool_)
    for j in range(len(bt)):
        alive[j] = now < 0 or (now - bt[j]) * 1e-9 <= max_dt
    m, k = z.shape
    new_i, old_j = windows(z, np.full(m, v_max * max_dt), bz)
    ok = np.zeros(len(new_i), np.bool_)
    dts = np.empty(len(new_i))
    for p in range(len(new_i)):
        i, j = new_i[p], old_j[p]
        dts[p] = (t[i] - bt[j]) * 1e-9
        if not (alive[j] and dts[p] >= min_dt and dts[p] <= max_dt):
            continue
        d2 = 0.0
        for a in range(k):
            d2 += (z[i, a] - bz[j, a]) * (z[i, a] - bz[j, a])
        ok[p] = np.sqrt(d2) <= v_max * dts[p]
    for p in range(len(new_i)):
        if ok[p]:
            alive[old_j[p]] = False
    return old_j[ok], new_i[ok], dts[ok], alive
