"""Particle track density for IPF / LM-IPF (spec 04 A.2, spec 02 §6), over arrays of tracks.

All clouds live in one array x (n_tracks, N, d) with weights w (n_tracks, N); row r is
the tracker's track r. CV motion in the system plane: d = 2k for k = 2 or 3 position
axes, state interleaved [x, vx, y, vy(, z, vz)] in metres and m/s, ``ConstantVelocity``
F(dt) and Q(dt) = Γ q Γᵀ (q = acceleration variance, m²/s⁴).

Recursion per scan (the tracker drives existence and association; this class does the
state):

* :meth:`predict` (A4): x^i ← F x^i + v^i, v^i ~ N(0, Q(dt)) per row's own dt; weights
  unchanged. Returns the predicted clouds and their moment-matched Gaussian (x̄, P̄ by
  A16), z_mean = H x̄ and S0 = H P̄ Hᵀ for gating boxes and clutter volumes. Pure: the
  stored state advances only in :meth:`update`.
* :meth:`likelihoods` (A5 [IMPL], A6, A7): gate on the moment-matched Gaussian,
  d² = (z − ŷ)ᵀ (S0 + R_j)⁻¹ (z − ŷ) < g (``fusion.association.gating.gate``: box pre-gate,
  then exact d²); for gated pairs the per-particle p^i_j (A6) against the plot's own R_j
  and the track likelihood p_j = Σ_i w^i p^i_j (A7). Both are divided by P_G = P(χ²_k < g)
  like the Gaussian trackers' p_j, so the tracker uses P_D P_G in (A11).
* :meth:`update` (A14): w^i ∝ w^i (β_0 + Σ_j β_j p^i_j / p_j), normalised — the posterior
  cloud is β_0 × the prior cloud plus Σ β_j × the cloud reweighted by plot j. MMSE mean
  and covariance (A16) are stored *before* resampling (lower variance, spec 02 §6 [IMPL]);
  then systematic resampling (A15) of all updated rows in one call, every scan
  (``neff_threshold=None``) or only where N_eff < neff_threshold · N; optional roughening.
* :meth:`estimate`: the stored MMSE x̂ (s, d), P (s, d, d).

No Python loop over tracks or particles: every step is a batched NumPy expression
(numba is not needed: searchsorted/bincount/matmul express all of it).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from skyfuse.fusion.association.gating import gate, gate_probability
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.tracker.density.base import GatedTable, Prediction

from .likelihood import pair_likelihoods
from .resampling import SCHEMES, resample, take
from .roughening import roughen
from .weights import effective_sample_size, normalise, weighted_moments


@dataclass
class ParticlePrediction(Prediction):
    """Predicted clouds of ``rows`` (the tracker's :class:`Prediction`, with z_mean = H x̄
    (s, k) and S0 = H P̄ Hᵀ (s, k, k) of the moment-matched cloud): x (s, N, d), prior
    weights w (s, N), moment-matched x_mean (s, d), P (s, d, d)."""

    x: np.ndarray
    w: np.ndarray
    x_mean: np.ndarray
    P: np.ndarray


@dataclass
class ParticleGatedTable(GatedTable):
    """Gated (track, plot) pairs (the tracker's :class:`GatedTable`): tp_track indexes the
    prediction's rows, tp_plot the plots; p (pairs,) = p_j / P_G (A7); lik (pairs, N) =
    p^i_j / P_G (A6); d2 (pairs,) the gate distance; p_gate = P_G."""

    lik: np.ndarray
    d2: np.ndarray
    p_gate: float


@lru_cache(maxsize=16)
def _gate_probability(g: float, k: int) -> float:
    """P_G of threshold g in k dimensions, computed once (scipy's chi² cdf per scan cost
    ~3 % of a particle tracker's step)."""
    return gate_probability(g, k)


def _noise_factor(Q: np.ndarray) -> np.ndarray:
    """G (s, d, r) with G Gᵀ = Q for PSD (possibly singular) Q, by eigh; directions of zero
    variance in every row are dropped (CV: r = number of axes), so that sampling draws
    only r normals per particle."""
    lam, V = np.linalg.eigh(Q)
    lam = np.maximum(lam, 0.0)
    live = (lam > 1e-12 * lam.max(axis=-1, keepdims=True)).any(axis=0)
    return (V * np.sqrt(lam)[:, None, :])[:, :, live]


class ParticleDensity:
    """Particle clouds of all tracks (spec 04 A.2), rows aligned with the tracker's tracks.

    model: ConstantVelocity (2 or 3 position axes); n_particles: N (source: 1000);
    neff_threshold: None = resample every scan (A15), else resample a row only when
    N_eff < neff_threshold · N; scheme: resampling scheme (source: systematic; any of
    ``fusion.particles.resampling.SCHEMES``); roughening: Gordon's K (0 = off); seed: RNG
    seed."""

    def __init__(
        self,
        model: ConstantVelocity,
        n_particles: int = 1000,
        neff_threshold: float | None = None,
        scheme: str = "systematic",
        roughening: float = 0.0,
        seed: int | None = 0,
    ) -> None:
        if scheme not in SCHEMES:
            raise ValueError(f"scheme = {scheme!r}: must be one of {sorted(SCHEMES)}")
        if neff_threshold is not None and not 0.0 < neff_threshold <= 1.0:
            raise ValueError(f"neff_threshold = {neff_threshold}: must be in (0, 1] or None")
        if n_particles < 1:
            raise ValueError(f"n_particles = {n_particles}: must be >= 1")
        self.model = model
        self.dim = model.dim
        self.n_particles = int(n_particles)
        self.neff_threshold = neff_threshold
        self.scheme = scheme
        self.roughening = roughening
        self.rng = np.random.default_rng(seed)
        self.pos = np.asarray(model.position_index)
        N, d = self.n_particles, self.dim
        self.x = np.zeros((0, N, d))
        self.w = np.zeros((0, N))
        self.mean = np.zeros((0, d))
        self.cov = np.zeros((0, d, d))

    @classmethod
    def from_config(cls, cfg) -> ParticleDensity:
        """The density of the ``ipf`` / ``lmipf`` trackers from a ``TrackerConfig``: CV with
        the configured q, ndim, q_vertical; ``particles``, ``resample_threshold``,
        ``resampling``, ``particle_seed``."""
        model = ConstantVelocity(q=cfg.q, ndim=cfg.ndim, q_vertical=cfg.q_vertical)
        return cls(
            model,
            n_particles=cfg.particles,
            neff_threshold=cfg.resample_threshold,
            scheme=cfg.resampling,
            seed=cfg.particle_seed,
        )

    def __len__(self) -> int:
        return len(self.x)

    def add(self, x: np.ndarray, P: np.ndarray) -> None:
        """Append tracks initiated as N(x, P): x (n, d), P (n, d, d) → N particles each."""
        x, P = np.atleast_2d(x), np.asarray(P).reshape(-1, self.dim, self.dim)
        n, N = len(x), self.n_particles
        G = _noise_factor(P)
        e = self.rng.standard_normal((n, N, G.shape[2]))
        cloud = x[:, None, :] + e @ np.swapaxes(G, 1, 2)
        self.x = np.concatenate([self.x, cloud])
        self.w = np.concatenate([self.w, np.full((n, N), 1.0 / N)])
        self.mean = np.concatenate([self.mean, x])
        self.cov = np.concatenate([self.cov, P])

    def keep(self, mask: np.ndarray) -> None:
        """Drop the tracks where ``mask`` is False."""
        mask = np.asarray(mask, bool)
        self.x, self.w = self.x[mask], self.w[mask]
        self.mean, self.cov = self.mean[mask], self.cov[mask]

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> ParticlePrediction:
        """Predicted clouds of ``rows`` over dt (s,) seconds (A4) and their moments (A16)."""
        rows = np.asarray(rows, np.int64)
        dt = np.broadcast_to(np.asarray(dt, float), rows.shape)
        F, Q = self.model.F(dt), self.model.Q(dt)
        G = _noise_factor(Q)
        noise = self.rng.standard_normal((len(rows), self.n_particles, G.shape[2]))
        x = self.x[rows] @ np.swapaxes(F, 1, 2) + noise @ np.swapaxes(G, 1, 2)
        w = self.w[rows]
        mean, P = weighted_moments(x, w)
        pos = self.pos
        return ParticlePrediction(
            rows, mean[:, pos], P[:, pos[:, None], pos[None, :]], x, w, mean, P
        )

    def likelihoods(
        self, pred: ParticlePrediction, z: np.ndarray, R: np.ndarray, g: float
    ) -> ParticleGatedTable:
        """Gate plots z (m, k) with covariances R (m, k, k) at threshold g (A5) and
        evaluate the per-particle and track likelihoods of the gated pairs (A6, A7)."""
        k = len(self.pos)
        pairs = gate(pred.z_mean, pred.S0, z, R, g)
        p_gate = _gate_probability(float(g), k)
        zp = pred.x[..., self.pos]
        lik = pair_likelihoods(zp, z, R, pairs.state, pairs.plot) / p_gate
        p = np.einsum("pn,pn->p", pred.w[pairs.state], lik)
        return ParticleGatedTable(pairs.state, pairs.plot, p, lik, pairs.d2, p_gate)

    def update(
        self,
        pred: ParticlePrediction,
        table: ParticleGatedTable,
        beta0: np.ndarray,
        beta: np.ndarray,
    ) -> None:
        """Weights by (A14), MMSE (A16) before resampling, then resampling (A15)."""
        if len(pred.rows) == 0:
            return
        factor = np.repeat(np.asarray(beta0, float)[:, None], self.n_particles, axis=1)
        if len(table):
            contrib = (np.asarray(beta) / np.maximum(table.p, 1e-300))[:, None] * table.lik
            order = np.argsort(table.tp_track, kind="stable")
            tracks, starts = np.unique(table.tp_track[order], return_index=True)
            factor[tracks] += np.add.reduceat(contrib[order], starts, axis=0)
        w = normalise(pred.w * factor)
        self.mean[pred.rows], self.cov[pred.rows] = weighted_moments(pred.x, w)
        x, w = self._resample(pred.x, w)
        self.x[pred.rows], self.w[pred.rows] = x, w

    def _resample(self, x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Resampling (systematic by default) of the rows due — all, or those with
        N_eff < threshold · N — in one call, then roughening if configured."""
        if self.neff_threshold is None:
            due = np.ones(len(w), bool)
        else:
            due = effective_sample_size(w) < self.neff_threshold * self.n_particles
        if due.all():  # the default: every row, no copies of the clouds
            xr = take(x, resample(w, self.rng, self.scheme))
            return roughen(xr, self.rng, self.roughening), np.full_like(w, 1.0 / w.shape[1])
        if due.any():
            x, w = x.copy(), w.copy()
            xr = take(x[due], resample(w[due], self.rng, self.scheme))
            x[due] = roughen(xr, self.rng, self.roughening)
            w[due] = 1.0 / self.n_particles
        return x, w

    def estimate(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """MMSE estimate x̂ (s, d) and covariance P (s, d, d) of ``rows`` (A16)."""
        rows = np.asarray(rows, np.int64)
        return self.mean[rows].copy(), self.cov[rows].copy()
