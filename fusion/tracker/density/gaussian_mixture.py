"""Gaussian-mixture track density with Singer N-scan memory: today's ITS components
(spec 02 §7; thesis 5.4-5.15; spec 03 §1.1 step 6). Depth 0 is IPDA (one Gaussian).

Every track is a mixture {ξ^c, x̂^c, P^c, h^c} in the flat :class:`Mixture` store of
:mod:`fusion.tracker.components`. Per batch:

* predict (5.4-5.5): x̂⁻ = F x̂, P⁻ = F P Fᵀ + Q per component over the track's dt with the
  linear motion model (CV, state [x, vx, y, vy(, z, vz)]);
* likelihoods (5.7-5.10, 4.17): gate all components × plots, p^c_i = N(ν; 0, S)/P_G and
  the track likelihoods p^τ_i = Σ_c ξ^c p^c_i per (track, plot) row;
* update: ITS children (5.12-5.15, :func:`fusion.tracker.its.component_update`), Singer
  N-scan merge, pruning (:mod:`fusion.tracker.components`), and the moment-matched track
  estimate (4.66-4.68), which :meth:`estimate` returns.

Plot-history ids are numbered here, one per plot of every ``likelihoods`` call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.association.gating import GatedPairs, gate
from skyfuse.fusion.filters.moment_matching import moment_match

from .. import components as comp
from ..component_slots import ComponentSlots
from ..its import component_update
from .base import GatedTable, Prediction, gate_probability_of


class MixturePrediction(Prediction):
    """Predicted components of the tracks ``rows``: weights w (C,), loc (C,) each
    component's index into rows, y (C, k), HPH (C, k, k) their predicted measurements.
    ``z_mean`` and ``S0`` (the track-level moment match, 4.66-4.68) are computed on first
    use: only the non-parametric clutter estimate needs them."""

    def __init__(self, rows: np.ndarray, w: np.ndarray, loc: np.ndarray, y, HPH, mix=None):
        self.rows, self.w, self.loc, self.y, self.HPH, self.mix = rows, w, loc, y, HPH, mix
        self._moments: tuple[np.ndarray, np.ndarray] | None = None

    def _track_moments(self) -> tuple[np.ndarray, np.ndarray]:
        if self._moments is None:
            _, z, S = moment_match(self.w, self.y, self.HPH, self.loc, len(self.rows))
            self._moments = (z, S)
        return self._moments

    @property
    def z_mean(self) -> np.ndarray:
        return self._track_moments()[0]

    @property
    def S0(self) -> np.ndarray:
        return self._track_moments()[1]


@dataclass
class MixtureTable(GatedTable):
    """Track × plot table plus the component-level pairs behind it: pairs (gated
    (component, plot)), p_pair (p^c_i per pair), pair_row (each pair's table row), R (m, k, k)
    and uid (m,) history ids of the batch's plots."""

    pairs: GatedPairs | None = None
    p_pair: np.ndarray | None = None
    pair_row: np.ndarray | None = None
    R: np.ndarray | None = None
    uid: np.ndarray | None = None


def track_table(
    loc: np.ndarray,
    comp_idx: np.ndarray,
    plot: np.ndarray,
    weight: np.ndarray,
    p_pair: np.ndarray,
    m: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(tp_track, tp_plot, p^τ_i = Σ_c ξ^c p^c_i (5.10), pair → table row) from gated
    (component ``comp_idx``, ``plot``) pairs; loc (C,) the components' tracks, weight (C,)
    their ξ, p_pair the pairs' p^c_i."""
    key = loc[comp_idx] * max(m, 1) + plot
    uniq, row = np.unique(key, return_inverse=True)
    row = row.reshape(-1)
    p_track = np.bincount(row, weights=weight[comp_idx] * p_pair, minlength=len(uniq))
    return uniq // max(m, 1), uniq % max(m, 1), p_track, row


class GaussianMixtureDensity:
    """ITS / IPDA Gaussian mixtures of all tracks (see the module docstring).

    model: a linear motion model with ``F(dt)``, ``Q(dt)``, ``H()``, ``dim``; depth: Singer
    memory N; prune_threshold, max_components: §7.11 pruning."""

    def __init__(
        self, model, depth: int, prune_threshold: float = 1e-3, max_components: int = 30
    ) -> None:
        self.model = model
        self.dim = model.dim
        self.H = model.H()
        self.pos = np.array(model.position_index)
        self.depth = depth
        self.prune_threshold = prune_threshold
        self.max_components = max_components
        self.slots = ComponentSlots(comp.Mixture.empty(self.dim, depth))
        self.x = np.zeros((0, self.dim))
        self.P = np.zeros((0, self.dim, self.dim))
        self.stats: dict[str, int] = {}
        self._next_uid = 1

    def __len__(self) -> int:
        return len(self.x)

    @property
    def mix(self) -> comp.Mixture:
        """Every component of every track (a copy of the live slots, in store order)."""
        return self.slots.live()

    @mix.setter
    def mix(self, value: comp.Mixture) -> None:
        self.slots = ComponentSlots.holding(value)

    def add(self, x: np.ndarray, P: np.ndarray) -> None:
        nn, n = len(x), len(self)
        if nn == 0:
            return
        hist = np.zeros((nn, self.depth), np.int64)
        new = comp.Mixture(n + np.arange(nn), np.ones(nn), x.copy(), P.copy(), hist)
        self.slots.append(new)
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, P])

    def keep(self, mask: np.ndarray) -> None:
        self.slots.keep(mask)
        self.x, self.P = self.x[mask], self.P[mask]

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> MixturePrediction:
        """Components of ``rows`` (sorted) predicted over dt (s,) s (5.4-5.5)."""
        inside = np.zeros(len(self), bool)
        inside[rows] = True
        pred = self.slots.tracks(inside)
        loc = np.searchsorted(rows, pred.track)
        dtc = np.asarray(dt, dtype=np.float64)[loc]
        pred.x, pred.P = self.model.predict(pred.x, pred.P, dtc)
        y = pred.x[:, self.pos]
        HPH = pred.P[:, self.pos][:, :, self.pos]
        return MixturePrediction(rows, pred.w, loc, y, HPH, pred)

    def likelihoods(
        self, pred: MixturePrediction, z: np.ndarray, R: np.ndarray, g: float
    ) -> MixtureTable:
        """Gate components × plots and tabulate p^τ_i (5.7-5.10)."""
        m = len(z)
        uid = self._next_uid + np.arange(m, dtype=np.int64)
        self._next_uid += m
        pairs = gate(pred.y, pred.HPH, z, R, g)
        p_pair = np.exp(pairs.log_pdf) / gate_probability_of(float(g), z.shape[1])
        tp_track, tp_plot, p_track, row = track_table(
            pred.loc, pairs.state, pairs.plot, pred.mix.w, p_pair, m
        )
        return MixtureTable(tp_track, tp_plot, p_track, pairs, p_pair, row, R, uid)

    def update(
        self, pred: MixturePrediction, table: MixtureTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        """ITS children (5.12-5.15), Singer merge, pruning, track estimates (4.66-4.68)."""
        children = component_update(
            pred.mix,
            pred.loc,
            table.pairs,
            table.p_pair,
            table.pair_row,
            table.p,
            beta0,
            beta,
            self.H,
            table.R,
            table.uid,
        )
        self.store_children(pred.rows, children, len(table.pairs))

    def store_children(self, rows: np.ndarray, children: comp.Mixture, pairs: int) -> None:
        """Singer merge and pruning of the updated components ``children`` of the tracks
        ``rows`` (sorted), which replace their components; track estimates (4.66-4.68).
        Also the out-of-sequence update's last step (:mod:`fusion.tracker.oosm_density`)."""
        merged = comp.singer_merge(children)
        kept = comp.prune(merged, self.prune_threshold, self.max_components, len(self))
        inside = np.zeros(len(self), bool)
        inside[rows] = True
        self.slots.replace(inside, kept)
        self.stats = {
            "gated_pairs": pairs,  # (component, plot) pairs
            "components_merged": len(merged),
            "components": len(self.slots),
        }
        loc = np.searchsorted(rows, kept.track)
        _, x, P = moment_match(kept.w, kept.x, kept.P, loc, len(rows))
        self.x[rows] = x
        self.P[rows] = P

    def estimate(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.x[rows].copy(), self.P[rows].copy()

    def estimates_view(self) -> tuple[np.ndarray, np.ndarray]:
        """x (n, dim), P (n, dim, dim) of all tracks, not copied: read only."""
        return self.x, self.P

    def component_counts(self) -> np.ndarray:
        """Mixture components per track (n,)."""
        return comp.components_per_track(self.slots.live(), len(self))
