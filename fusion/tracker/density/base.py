"""The track-density interface of the existence trackers (spec 02 §7, spec 03 §1; the
"predictor/updater" of Stone Soup's separation, over arrays of tracks).

A :class:`TrackDensity` holds the kinematic state of *all* tracks of a
:class:`fusion.tracker.Tracker`, rows aligned with the tracker's track arrays (ids,
existence, …). The tracker never looks inside: per batch it calls

1. ``predict(rows, dt)`` — the tracks the batch could have seen, each over its own dt (s),
   to their illumination times. The returned :class:`Prediction` carries at least the
   track-level predicted measurement mean ``z_mean`` (s, k) and ``S0 = H P Hᵀ`` (s, k, k)
   of the moment-matched predicted density (for the non-parametric clutter estimate, 2.35,
   and the coverage test);
2. ``likelihoods(pred, z, R, g)`` — the gated track × plot table (5.7-5.10): rows
   ``tp_track`` (index into ``pred.rows``), ``tp_plot`` and ``p`` = p^τ_i, the track's
   measurement likelihood of plot i divided by the gate probability P_G (4.17, 5.10);
3. association (``fusion.tracker.associators``) turns that table, the clutter density and
   the predicted existence into β₀ per track and β_i per table row (2.38, 6.8, 6.22);
4. ``update(pred, table, beta0, beta)`` — the posterior density of every predicted track
   (ITS children 5.12-5.15 or their analogue: particle weights, IMM mode probabilities);
5. ``estimate(rows)`` — the MMSE estimate and covariance (4.66-4.68) in the output layout
   of ``dim`` entries (the CV layout [x, vx, y, vy(, z, vz)], m and m/s, system frame).

``add(x, P)`` starts tracks from Gaussian initial states (initiation, 3.25-3.27) and
``keep(mask)`` drops tracks; the rows of the others close up in order. Implementations:
:class:`~fusion.tracker.density.gaussian_mixture.GaussianMixtureDensity` (ITS components
with Singer N-scan memory; one Gaussian = IPDA) and
:class:`~fusion.tracker.density.imm_mixture.IMMMixtureDensity` (every component an IMM).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol, runtime_checkable

import numpy as np
from skyfuse.fusion.association.gating import gate_probability


@lru_cache(maxsize=32)
def gate_probability_of(g: float, k: int) -> float:
    """P_G = P(χ²_k ≤ g) (4.17) for the gate threshold ``g`` in ``k`` dimensions,
    computed once per (g, k): every batch gates with the same threshold, and the χ²
    cdf costs more than the rest of a small batch's table."""
    return float(gate_probability(g, k))


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

    def __len__(self) -> int: ...

    def add(self, x: np.ndarray, P: np.ndarray) -> None:
        """Append tracks with Gaussian initial states x (n, d), P (n, d, d)."""

    def keep(self, mask: np.ndarray) -> None:
        """Keep the tracks with mask (n,) True, in order."""

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> Prediction:
        """Predict tracks ``rows`` (s,) over ``dt`` (s,) seconds (not stored)."""

    def likelihoods(self, pred: Prediction, z: np.ndarray, R: np.ndarray, g: float) -> GatedTable:
        """Gate plots z (m, k), R (m, k, k) with threshold g and tabulate p = N / P_G."""

    def update(
        self, pred: Prediction, table: GatedTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        """Store the posterior of the predicted tracks given β₀ (s,) and β (len(table),)."""

    def estimate(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """MMSE estimate x (s, dim) and covariance P (s, dim, dim) of tracks ``rows``."""
