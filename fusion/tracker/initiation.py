"""Track initiation from plots no existing track selected ([thesis] §3.5, §7.1).

* Two-point differencing (3.25-3.27): a plot z₁ kept from an earlier batch and a new plot
  z₂ with ‖z₂ − z₁‖ ≤ v_max Δt start a track (the formulas live in
  :mod:`fusion.filters.initiation`, the one initiation of skyfuse).
* One-point: x̂ = [z, 0] per axis, P = diag(R, v_max²/3).

Unused plots wait in a :class:`PlotBuffer` for ``max_dt`` seconds; a buffered plot that
forms pairs is consumed by them.
"""

from __future__ import annotations

import numpy as np
from skyfuse.fusion.association.gating import window_pairs
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
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (buffer index, new plot index, Δt s) with min_dt ≤ Δt ≤ max_dt and
    ‖z₂ − z₁‖ ≤ v_max Δt (the maximum-velocity criterion of [thesis] §7.1)."""
    if len(buffer) == 0 or len(z) == 0:
        e = np.zeros(0, np.int64)
        return e, e, np.zeros(0)
    radius = np.full(len(z), v_max * max_dt)
    new_i, old_j = window_pairs(z, radius, buffer.z)
    dt = (time[new_i] - buffer.time[old_j]) * 1e-9
    d = z[new_i] - buffer.z[old_j]
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))  # ‖z₂ − z₁‖
    ok = (dt >= min_dt) & (dt <= max_dt) & (dist <= v_max * dt)
    return old_j[ok], new_i[ok], dt[ok]
