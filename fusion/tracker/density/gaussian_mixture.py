"""Gaussian-mixture track density with Singer N-scan memory: the ITS components of
[thesis] ch. 4-5 (5.4-5.15). Depth 0 is IPDA (one Gaussian, [thesis] 2.37-2.41).

Every track is a mixture {ξ^c, x̂^c, P^c, h^c} in the flat :class:`Mixture` store of
:mod:`fusion.tracker.components` (in slots, :mod:`fusion.tracker.component_slots`); the
track-level estimate x̂, P is two columns of the tracker's track store
(:mod:`fusion.tracker.store`). Per batch:

* predict (5.4-5.5): x̂⁻ = F x̂, P⁻ = F P Fᵀ + Q per component over the track's dt with the
  linear motion model (CV, state [x, vx, y, vy(, z, vz)]);
* likelihoods (5.7-5.10, 4.17): gate all components × plots, p^c_i = N(ν; 0, S)/P_G and
  the track likelihoods p^τ_i = Σ_c ξ^c p^c_i per (track, plot) row;
* update: ITS children (5.12-5.15, :func:`fusion.tracker.its.component_update`), Singer
  N-scan merge, pruning (:mod:`fusion.tracker.components`), and the moment-matched track
  estimate (4.66-4.68), which :meth:`estimate` returns.

Late plots (:class:`~.base.Retrodiction`, :mod:`fusion.tracker.oosm`): every component c
is retrodicted with the CV model from its own posterior (x̂^c, P^c) and the track's last
prior (Bar-Shalom 2002, A1, (O1)-(O4)); the late plots are gated and weighed by
:meth:`likelihoods` on the retrodicted components (p^c_i = N(z_i; H x̂^c(τ|k), S^c_i(τ)) /
P_G); the children are those of 5.12-5.15 with the Kalman update replaced by the OOSM
update (O5): the "no plot" child keeps x̂^c, P^c with weight β₀ ξ^c, the child of plot i
is x̂^c(k|τ), P^c(k|τ) with weight β_i ξ^c p^c_i / p^τ_i; then the same Singer merge,
pruning and estimate. The late plot enters the plot history as one more scan.

Plot-history ids are numbered here, one per plot of every ``likelihoods`` call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from skyfuse.fusion.association.gating import GatedPairs, gate
from skyfuse.fusion.filters.kalman import update_with_innovation
from skyfuse.fusion.filters.moment_matching import moment_match
from skyfuse.fusion.models.cv import ConstantVelocity
from skyfuse.schemas.snapshot import entry, mapping

from .. import components as comp
from ..component_slots import ComponentSlots
from ..components_kernel import its_update, merge_prune_estimate
from ..its import shift_history
from ..oosm import oosm_update, retrodict
from .base import GatedTable, Prediction, estimate_group, gate_probability_of


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
    their ξ, p_pair the pairs' p^c_i. Rows in (track, plot) order; the sums in pair order
    (one compiled loop, :func:`_track_table`)."""
    c = np.ascontiguousarray
    return _track_table(c(loc, dtype=np.int64), c(comp_idx, dtype=np.int64),
                        c(plot, dtype=np.int64), c(weight, dtype=np.float64),
                        c(p_pair, dtype=np.float64), int(m))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _track_table(loc, comp_idx, plot, weight, p_pair, m):
    M = max(m, 1)
    n = len(comp_idx)
    key = np.empty(n, np.int64)
    for q in range(n):
        key[q] = loc[comp_idx[q]] * M + plot[q]
    order = np.argsort(key)
    row = np.empty(n, np.int64)
    uniq = np.empty(n, np.int64)
    u = 0
    for s in range(n):
        q = order[s]
        if s == 0 or key[q] != uniq[u - 1]:
            uniq[u] = key[q]
            u += 1
        row[q] = u - 1
    p = np.zeros(u)
    for q in range(n):
        p[row[q]] += weight[comp_idx[q]] * p_pair[q]
    return uniq[:u] // M, uniq[:u] % M, p, row


class MixtureRetrodiction(MixturePrediction):
    """The retrodicted components of late tracks (what :meth:`likelihoods` gates) and
    what the out-of-sequence update needs: the current components ``current`` and the
    cross terms ``cross`` (C (C, d, d) of (O1)-(O4), :func:`fusion.tracker.oosm.retrodict`)."""

    def __init__(self, rows, w, loc, y, HPH, mix, current, cross) -> None:
        super().__init__(rows, w, loc, y, HPH, mix)
        self.current, self.cross = current, cross


class GaussianMixtureDensity:
    """ITS / IPDA Gaussian mixtures of all tracks (see the module docstring).

    model: a linear motion model with ``F(dt)``, ``Q(dt)``, ``H()``, ``dim``; depth: Singer
    memory N; prune_threshold, max_components: the pruning of the mixtures."""

    late_plots = "retrodict"

    def __init__(
        self, model, depth: int, prune_threshold: float = 1e-3, max_components: int = 30
    ) -> None:
        self.model = model
        self.dim = model.dim
        self.mode_dims = (model.dim,)
        self.H = model.H()
        self.pos = np.array(model.position_index)
        self.depth = depth
        self.prune_threshold = prune_threshold
        self.max_components = max_components
        self.slots = ComponentSlots(comp.Mixture.empty(self.dim, depth))
        self.tracks = None
        self.stats: dict[str, int] = {}
        self._next_uid = 1

    @classmethod
    def from_config(cls, cfg) -> GaussianMixtureDensity:
        """The ``cv`` motion of a ``TrackerConfig``: CV (q, ndim, q_vertical), the kind's
        Singer depth, pruning."""
        model = ConstantVelocity(q=cfg.q, ndim=cfg.ndim, q_vertical=cfg.q_vertical)
        return cls(model, cfg.memory_depth, cfg.prune_threshold, cfg.max_components)

    # ------------------------------------------------------------------ tracks
    def attach(self, tracks) -> None:
        """Columns ``x`` (n, d), ``P`` (n, d, d): the track estimates; new tracks get one
        component (ξ = 1, their initial Gaussian, empty history)."""
        tracks.declare(estimate_group(self.dim, self._appended, self._kept))
        self.tracks = tracks

    def _appended(self, rows: np.ndarray, new) -> None:
        hist = np.zeros((len(rows), self.depth), np.int64)
        self.slots.append(comp.Mixture(rows, np.ones(len(rows)), new.x.copy(), new.P.copy(), hist))

    def _kept(self, mask: np.ndarray) -> None:
        self.slots.keep(mask)

    def __len__(self) -> int:
        return len(self.tracks)

    @property
    def mix(self) -> comp.Mixture:
        """Every component of every track (a copy of the live slots, in store order)."""
        return self.slots.live()

    @mix.setter
    def mix(self, value: comp.Mixture) -> None:
        self.slots = ComponentSlots.holding(value)

    # ------------------------------------------------------------------ one batch
    def predict(self, rows: np.ndarray, dt: np.ndarray) -> MixturePrediction:
        """Components of ``rows`` (sorted) predicted over dt (s,) s (5.4-5.5)."""
        pred, loc = self.slots.rows(rows, len(self))
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
        """ITS children (5.12-5.15), Singer merge, pruning, track estimates (4.66-4.68):
        one compiled call (:func:`~..components_kernel.its_update`)."""
        mix, pairs, c = pred.mix, table.pairs, np.ascontiguousarray
        kept, merged, x, P = its_update(
            (mix.track, mix.w, mix.x, mix.P, mix.hist),
            pred.loc,
            c(beta0, dtype=np.float64),
            (pairs.state, pairs.plot, table.pair_row, pairs.nu, pairs.S),
            table.p_pair,
            table.p,
            c(beta, dtype=np.float64),
            self.H,
            c(table.R, dtype=np.float64),
            table.uid,
            pred.rows,
            (float(self.prune_threshold), int(self.max_components), len(self)),
        )
        self._store(pred.rows, kept, merged, len(pairs), x, P)

    def store_children(self, rows: np.ndarray, children: comp.Mixture, pairs: int) -> None:
        """Singer merge and pruning of the updated components ``children`` of the tracks
        ``rows`` (sorted), which replace their components; track estimates (4.66-4.68).
        The last step of the out-of-sequence update (:meth:`update_late`)."""
        c = np.ascontiguousarray
        kept, merged, x, P = merge_prune_estimate(
            (c(children.track, dtype=np.int64), c(children.w, dtype=np.float64),
             c(children.x, dtype=np.float64), c(children.P, dtype=np.float64),
             c(children.hist, dtype=np.int64)),
            rows, float(self.prune_threshold), int(self.max_components), len(self),
        )  # fmt: skip
        self._store(rows, kept, merged, pairs, x, P)

    def _store(self, rows, kept: tuple, merged: int, pairs: int, x, P) -> None:
        """The kept components replace those of ``rows``; their track estimates x, P."""
        self.slots.replace_rows(rows, len(self), comp.Mixture(*kept))
        self.stats = {
            "gated_pairs": pairs,  # (component, plot) pairs
            "components_merged": merged,
            "components": len(self.slots),
        }
        self.tracks.x[rows] = x
        self.tracks.P[rows] = P

    def estimate(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.tracks.x[rows].copy(), self.tracks.P[rows].copy()

    def estimates_view(self) -> tuple[np.ndarray, np.ndarray]:
        """x (n, dim), P (n, dim, dim) of all tracks, not copied: read only."""
        return self.tracks.x, self.tracks.P

    def component_counts(self) -> np.ndarray:
        """Mixture components per track (n,)."""
        return comp.components_per_track(self.slots.live(), len(self))

    # ------------------------------------------------------------------ late plots
    def track_priors(self, pred: MixturePrediction) -> tuple[list, list]:
        """The track-level prior of each predicted track: the moment match of its
        predicted components (4.66-4.68), one mode."""
        _, x, P = moment_match(pred.mix.w, pred.mix.x, pred.mix.P, pred.loc, len(pred.rows))
        return [x], [P]

    def retrodict(self, rows: np.ndarray, lag: np.ndarray, priors) -> MixtureRetrodiction:
        """The components of ``rows`` retrodicted over ``lag`` (O1-O4)."""
        cur, loc = self.slots.rows(rows, len(self))
        known, xs, Ps = priors
        x, P, C = retrodict(self.model, cur.x, cur.P, lag[loc], xs[0][loc], Ps[0][loc], known[loc])
        retro = comp.Mixture(cur.track, cur.w, x, P, cur.hist)
        pos = self.pos
        return MixtureRetrodiction(rows, cur.w, loc, x[:, pos], P[:, pos][:, :, pos], retro, cur, C)

    def update_late(
        self, pred: MixtureRetrodiction, table: MixtureTable, beta0: np.ndarray, beta: np.ndarray
    ) -> None:
        """The children of the module docstring ("late plots"), merged and pruned."""
        cur = pred.current
        hist0 = shift_history(cur.hist, np.zeros(len(cur), np.int64))
        children = comp.Mixture(cur.track, cur.w * beta0[pred.loc], cur.x, cur.P, hist0)
        pairs = table.pairs
        if len(pairs):
            c = pairs.state
            w = cur.w[c] * beta[table.pair_row] * table.p_pair / table.p[table.pair_row]
            x, P = oosm_update(cur.x[c], cur.P[c], pred.cross[c], self.H, pairs.nu, pairs.S)
            hist = shift_history(cur.hist[c], table.uid[pairs.plot])
            children = comp.Mixture.concat([children, comp.Mixture(cur.track[c], w, x, P, hist)])
            children = children.take(np.flatnonzero(children.w > 0.0))
        self.store_children(pred.rows, children, len(table.tp_track))

    # ------------------------------------------------------------------ snapshots
    def to_snapshot(self) -> dict:
        """The components (the estimates are track-store columns) and the next plot
        history id."""
        return {"components": self.slots.to_snapshot(), "next_uid": self._next_uid}

    def from_snapshot(self, snap) -> None:
        snap = mapping(snap, "density")
        empty = comp.Mixture.empty(self.dim, self.depth)
        slots = ComponentSlots.from_snapshot(snap.get("components"), empty, len(self))
        self.slots, self._next_uid = slots, entry(snap, "next_uid", int)

    @staticmethod
    def warm_up() -> None:
        """Load the compiled kernels of this density (CV prediction, the Kalman update of
        the gated pairs, moment matching, the update with its merge and pruning) on tiny
        inputs."""
        P = np.stack([np.eye(4), 2.0 * np.eye(4)])
        x = np.zeros((2, 4))
        ConstantVelocity().predict(x, P, np.array([1.0, 2.0]))
        H = ConstantVelocity().H()
        S = H @ P @ H.T + np.eye(2)
        update_with_innovation(x, P, H, S, np.ones((2, 2)), np.stack([np.eye(2)] * 2))
        moment_match(np.array([0.4, 0.6]), x, P, np.array([0, 0]), 1)
        i2, w2, h2 = np.array([0, 0]), np.array([0.5, 0.5]), np.zeros((2, 1), np.int64)
        i1 = np.zeros(1, np.int64)
        its_update((i2, w2, x, P, h2), i2, np.array([0.5]),
                   (i1, i1, i1, np.ones((1, 2)), S[:1].copy()), np.ones(1), np.ones(1),
                   np.ones(1), H, np.eye(2)[None].copy(), np.ones(1, np.int64), i1,
                   (1e-3, 30, 1))  # fmt: skip
        merge_prune_estimate((i2, w2, x, P, h2), i1, 1e-3, 30, 1)
