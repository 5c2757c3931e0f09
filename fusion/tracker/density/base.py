"""The track-density interface of the existence trackers: the "predictor/updater" of Stone
Soup's separation, over arrays of tracks (docs/concepts/tracker-parts.md).

A :class:`TrackDensity` holds the kinematic state of *all* tracks of a
:class:`fusion.tracker.Tracker`. Its per-track state is columns of the tracker's track
store (:mod:`fusion.tracker.store`), declared by :meth:`~TrackDensity.attach`; per-track
state of variable size (mixture components) is the density's own store, kept in step
with the track rows by the hooks of its column group. The tracker never looks inside:
per batch it calls

1. ``predict(rows, dt)`` — the tracks the batch could have seen, each over its own dt (s),
   to their illumination times. The returned :class:`Prediction` carries at least the
   track-level predicted measurement mean ``z_mean`` (s, k) and ``S0 = H P Hᵀ`` (s, k, k)
   of the moment-matched predicted density (for the non-parametric clutter estimate,
   [thesis] 2.35, and the coverage test);
2. ``likelihoods(pred, z, R, g)`` — the gated track × plot table ([thesis] 5.7-5.10): rows
   ``tp_track`` (index into ``pred.rows``), ``tp_plot`` and ``p`` = p^τ_i, the track's
   measurement likelihood of plot i divided by the gate probability P_G ([thesis] 4.17,
   5.10);
3. association (:mod:`fusion.tracker.associators`) turns that table, the clutter density
   and the predicted existence into β₀ per track and β_i per table row ([thesis] 2.38,
   6.8, 6.22);
4. ``update(pred, table, beta0, beta)`` — the posterior density of every predicted track
   (ITS children and the Singer merge, [thesis] 5.12-5.15; particle weights, [LM-IPF]
   eq. 11; IMM mode probabilities);
5. ``estimate(rows)`` — the MMSE estimate and covariance ([thesis] 4.66-4.68) in the
   output layout of ``dim`` entries (CV [x, vx, y, vy(, z, vz)], m and m/s, system frame).

New tracks start from Gaussian initial states ([thesis] 3.25-3.27): the store's
``append`` gives every group the :class:`~fusion.tracker.store.NewTracks`; dropped tracks
leave by the store's ``keep``.

**Late plots.** A density declares in ``late_plots`` how the tracker treats a plot older
than a track's current time. ``"retrodict"``: it also implements :class:`Retrodiction`,
the out-of-sequence update (Bar-Shalom 2002, A1, :mod:`fusion.tracker.oosm`); the
out-of-sequence pass (:mod:`fusion.tracker.oosm_pass`) keeps the prior of every track's
last ordinary update (``track_priors``), retrodicts the late tracks (``retrodict``, a
prediction the density's own ``likelihoods`` gates and weighs) and applies the associated
plots to the current state (``update_late``). ``"current"``: late plots are applied at the
track's current time, like any plot (the particle density).

**Warm-up.** A density class may offer ``warm_up()`` (a static method): it calls the
compiled kernels only this density uses once, on tiny inputs; the registry's
``warm_up_parts`` calls it for every registered density (:mod:`fusion.tracker.kernel_warmup`).

**Snapshots.** ``to_snapshot()`` / ``from_snapshot(snapshot)``: the density's state that is
not a column of the track store (its component store, counters, random generator) as
named values (:mod:`schemas.snapshot`); the columns are in the track store's snapshot.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal, Protocol, runtime_checkable

import numpy as np
from skyfuse.fusion.association.gating import gate_probability

from ..store import Column, ColumnGroup


@lru_cache(maxsize=32)
def gate_probability_of(g: float, k: int) -> float:
    """P_G = P(χ²_k ≤ g) ([thesis] 4.17) for the gate threshold ``g`` in ``k``
    dimensions, computed once per (g, k): every batch gates with the same threshold, and
    the χ² cdf costs more than the rest of a small batch's table."""
    return float(gate_probability(g, k))


def estimate_group(dim: int, appended=None, kept=None) -> ColumnGroup:
    """The ``density`` column group of a density whose per-track columns are its track
    estimate: ``x`` (n, dim), ``P`` (n, dim, dim) in the output layout, a new track's being
    its initial Gaussian; ``appended`` / ``kept``: the hooks of the density's own store
    (mixture components)."""
    columns = (Column("x", np.float64, (dim,), doc="track estimate, output layout"),
               Column("P", np.float64, (dim, dim), doc="its covariance"))  # fmt: skip
    return ColumnGroup("density", columns, init=_initial_estimate, appended=appended, kept=kept)


def _initial_estimate(new) -> dict:
    return {"x": new.x, "P": new.P}


@dataclass
class Prediction:
    """Predicted density of the tracks ``rows`` (s,): z_mean (s, k) and S0 = H P Hᵀ
    (s, k, k) of the track-level (moment-matched) prediction. Implementations subclass it
    to carry their own predicted state (components, particles, modes)."""

    rows: np.ndarray
    z_mean: np.ndarray
    S0: np.ndarray

    def __len__(self) -> int:
        return len(self.rows)


@dataclass
class GatedTable:
    """The gated track × plot table: tp_track (t,) index into ``Prediction.rows``,
    tp_plot (t,) plot index, p (t,) = likelihood / P_G of the pair. Implementations
    subclass it to keep what their update needs (e.g. component-level pairs)."""

    tp_track: np.ndarray
    tp_plot: np.ndarray
    p: np.ndarray

    def __len__(self) -> int:
        return len(self.tp_track)

    @property
    def plots_gated(self) -> np.ndarray:
        """Indices of the plots some track gated (they do not start tracks)."""
        return np.unique(self.tp_plot)


@runtime_checkable
class TrackDensity(Protocol):
    """All tracks' kinematic densities; see the module docstring for the call sequence."""

    dim: int
    late_plots: Literal["retrodict", "current"]
    stats: dict[str, int]
    """Counters of the last update (components, pairs …), added to the batch's stats."""

    def attach(self, tracks) -> None:
        """Declare this density's columns (and hooks) in the track store ``tracks`` (a
        :class:`~fusion.tracker.store.Table` without rows) and keep it."""

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> Prediction:
        """Predict tracks ``rows`` (s,) over ``dt`` (s,) seconds (not stored)."""

    def likelihoods(self, pred: Prediction, z: np.ndarray, R: np.ndarray, g: float) -> GatedTable:
        """Gate plots z (m, k), R (m, k, k) with threshold g and tabulate p = N / P_G."""

    def update(
        self, pred: Prediction, table: GatedTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        """Store the posterior of the predicted tracks given β₀ (s,) and β (len(table),)."""

    def estimate(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """MMSE estimate x (s, dim) and covariance P (s, dim, dim) of tracks ``rows``
        (copies)."""

    def estimates_view(self) -> tuple[np.ndarray, np.ndarray]:
        """x (n, dim), P (n, dim, dim) of all tracks, not copied: read only."""

    def component_counts(self) -> np.ndarray:
        """Components per track (n,) (1 where a track is not a mixture)."""

    def to_snapshot(self) -> dict:
        """The state that is not a track-store column (module docstring)."""

    def from_snapshot(self, snap: dict) -> None:
        """Hold the state of :meth:`to_snapshot` (after the track store's rows)."""


@runtime_checkable
class Retrodiction(Protocol):
    """The out-of-sequence update of a density whose ``late_plots`` is ``"retrodict"``
    (module docstring; the equations are in :mod:`fusion.tracker.oosm`)."""

    mode_dims: tuple[int, ...]
    """State dimension of each mode (one mode: a Gaussian mixture)."""

    def track_priors(self, pred: Prediction) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The track-level predicted state per mode, x[j] (s, d_j), P[j] (s, d_j, d_j), of a
        prediction: the prior of the update that follows (kept for the A1 update)."""

    def retrodict(self, rows: np.ndarray, lag: np.ndarray, priors) -> Prediction:
        """The tracks ``rows`` (sorted) retrodicted over ``lag`` (s,) seconds, as a
        prediction for :meth:`TrackDensity.likelihoods` and :meth:`update_late`.
        ``priors``: (known (s,), x[j] (s, d_j), P[j] (s, d_j, d_j)), the last step's
        priors where ``known``."""

    def update_late(
        self, pred: Prediction, table: GatedTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        """The out-of-sequence update of the retrodicted tracks given β₀ and β: their
        current state takes the late plots (the track times do not change)."""
