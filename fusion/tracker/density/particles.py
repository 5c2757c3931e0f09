"""Particle track density of the IPF / LM-IPF trackers ([LM-IPF]; [thesis] §3.4-3.6, the
IPF), over arrays of tracks.

Every track's cloud is one row of the tracker's track store (:mod:`fusion.tracker.store`):
``particles`` (n, N, d) with ``weights`` (n, N) ([LM-IPF] eq. 3-4), and its MMSE estimate
``x`` (n, d), ``P`` (n, d, d). CV motion in the system plane: d = 2k for k = 2 or 3 position
axes, state interleaved [x, vx, y, vy(, z, vz)] in metres and m/s, ``ConstantVelocity``
F(dt) and Q(dt) = Γ q Γᵀ (q = acceleration variance, m²/s⁴).

Recursion per scan (the tracker drives existence and association; this class does the
state):

* :meth:`predict` ([LM-IPF] eq. 6): x^i ← F x^i + v^i, v^i ~ N(0, Q(dt)) per row's own dt;
  weights unchanged. Returns the predicted clouds and their moment-matched Gaussian (x̄,
  P̄, the weighted mean and covariance of the cloud), z_mean = H x̄ and S0 = H P̄ Hᵀ for
  gating boxes and clutter volumes. Pure: the stored state advances only in :meth:`update`.
* :meth:`likelihoods` ([LM-IPF] eq. 7-9): gate on the moment-matched Gaussian,
  d² = (z − ŷ)ᵀ (S0 + R_j)⁻¹ (z − ŷ) < g (``fusion.association.gating.gate``: box pre-gate,
  then exact d²; the paper's "two-tier measurement selection", its details unspecified
  [IMPL]); for gated pairs the per-particle p^i_j (eq. 8, with the normalisation
  1/(2π√|R|) of a 2-D Gaussian: the paper's 1/√(2π|R|) is a typo) against the plot's own
  R_j and the track likelihood p_j = Σ_i w^i p^i_j (eq. 9). Both are divided by
  P_G = P(χ²_k < g) like the Gaussian trackers' p_j ([thesis] 4.17), so the tracker uses
  P_D P_G.
* :meth:`update` ([LM-IPF] eq. 11): w^i ∝ w^i (β_0 + Σ_j β_j p^i_j / p_j), normalised — the
  posterior cloud is β_0 × the prior cloud plus Σ β_j × the cloud reweighted by plot j.
  MMSE mean and covariance are stored *before* resampling (lower variance [IMPL]); then
  systematic resampling ([thesis] §3.4, the scheme of the IPF) of all updated rows in one
  call, every scan (``neff_threshold=None``) or only where N_eff < neff_threshold · N;
  optional roughening.
* :meth:`estimate`: the stored MMSE x̂ (s, d), P (s, d, d).

Late plots are applied at the track's current time (``late_plots = "current"``): the
out-of-sequence retrodiction of a cloud is not implemented.

No Python loop over tracks or particles: every step is a batched NumPy expression
(numba is not needed: searchsorted/bincount/matmul express all of it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.fusion.association.gating import gate
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.particles.likelihood import pair_likelihoods
from skyfuse.fusion.particles.resampling import SCHEMES, resample, take
from skyfuse.fusion.particles.roughening import roughen
from skyfuse.fusion.particles.weights import effective_sample_size, normalise, weighted_moments
from skyfuse.schemas.snapshot import SnapshotError, entry, mapping

from ..store import Column, ColumnGroup
from .base import GatedTable, Prediction, gate_probability_of


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
    prediction's rows, tp_plot the plots; p (pairs,) = p_j / P_G ([LM-IPF] eq. 9); lik
    (pairs, N) = p^i_j / P_G (eq. 8); d2 (pairs,) the gate distance; p_gate = P_G."""

    lik: np.ndarray
    d2: np.ndarray
    p_gate: float


def _noise_factor(Q: np.ndarray) -> np.ndarray:
    """G (s, d, r) with G Gᵀ = Q for PSD (possibly singular) Q, by eigh; directions of zero
    variance in every row are dropped (CV: r = number of axes), so that sampling draws
    only r normals per particle."""
    lam, V = np.linalg.eigh(Q)
    lam = np.maximum(lam, 0.0)
    live = (lam > 1e-12 * lam.max(axis=-1, keepdims=True)).any(axis=0)
    return (V * np.sqrt(lam)[:, None, :])[:, :, live]


class ParticleDensity:
    """Particle clouds of all tracks (see the module docstring).

    model: ConstantVelocity (2 or 3 position axes); n_particles: N (source: 1000);
    neff_threshold: None = resample every scan, else resample a row only when
    N_eff < neff_threshold · N; scheme: resampling scheme (source: systematic; any of
    ``fusion.particles.resampling.SCHEMES``); roughening: Gordon's K (0 = off); seed: RNG
    seed."""

    late_plots = "current"

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
        self.tracks = None
        self.stats: dict[str, int] = {}

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

    def attach(self, tracks) -> None:
        """Columns ``particles`` (n, N, d), ``weights`` (n, N), ``x`` (n, d), ``P``
        (n, d, d); a new track's cloud is N draws of N(x, P) with weights 1/N."""
        N, d = self.n_particles, self.dim
        tracks.declare(
            ColumnGroup(
                "density",
                (Column("particles", np.float64, (N, d), doc="cloud, [LM-IPF] eq. 3"),
                 Column("weights", np.float64, (N,), fill=1.0 / N, doc="its weights, eq. 4"),
                 Column("x", np.float64, (d,), doc="MMSE estimate of the cloud"),
                 Column("P", np.float64, (d, d), doc="its covariance")),
                init=self._new_clouds,
            )
        )  # fmt: skip
        self.tracks = tracks

    def _new_clouds(self, new) -> dict:
        """Tracks initiated as N(x, P): x (n, d), P (n, d, d) → N particles each."""
        x, P = np.atleast_2d(new.x), np.asarray(new.P).reshape(-1, self.dim, self.dim)
        G = _noise_factor(P)
        e = self.rng.standard_normal((len(x), self.n_particles, G.shape[2]))
        return {"particles": x[:, None, :] + e @ np.swapaxes(G, 1, 2), "x": x, "P": P}

    def __len__(self) -> int:
        return len(self.tracks)

    def predict(self, rows: np.ndarray, dt: np.ndarray) -> ParticlePrediction:
        """Predicted clouds of ``rows`` over dt (s,) seconds ([LM-IPF] eq. 6) and their
        weighted moments."""
        rows = np.asarray(rows, np.int64)
        dt = np.broadcast_to(np.asarray(dt, float), rows.shape)
        F, Q = self.model.F(dt), self.model.Q(dt)
        G = _noise_factor(Q)
        noise = self.rng.standard_normal((len(rows), self.n_particles, G.shape[2]))
        x = self.tracks.particles[rows] @ np.swapaxes(F, 1, 2) + noise @ np.swapaxes(G, 1, 2)
        w = self.tracks.weights[rows]
        mean, P = weighted_moments(x, w)
        pos = self.pos
        return ParticlePrediction(
            rows, mean[:, pos], P[:, pos[:, None], pos[None, :]], x, w, mean, P
        )

    def likelihoods(
        self, pred: ParticlePrediction, z: np.ndarray, R: np.ndarray, g: float
    ) -> ParticleGatedTable:
        """Gate plots z (m, k) with covariances R (m, k, k) at threshold g and evaluate the
        per-particle and track likelihoods of the gated pairs ([LM-IPF] eq. 7-9)."""
        k = len(self.pos)
        pairs = gate(pred.z_mean, pred.S0, z, R, g)
        p_gate = gate_probability_of(float(g), k)
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
        """Weights by [LM-IPF] eq. 11, the MMSE estimate before resampling, then resampling."""
        if len(pred.rows) == 0:
            return
        factor = np.repeat(np.asarray(beta0, float)[:, None], self.n_particles, axis=1)
        if len(table):
            contrib = (np.asarray(beta) / np.maximum(table.p, 1e-300))[:, None] * table.lik
            order = np.argsort(table.tp_track, kind="stable")
            tracks, starts = np.unique(table.tp_track[order], return_index=True)
            factor[tracks] += np.add.reduceat(contrib[order], starts, axis=0)
        w = normalise(pred.w * factor)
        t = self.tracks
        t.x[pred.rows], t.P[pred.rows] = weighted_moments(pred.x, w)
        t.particles[pred.rows], t.weights[pred.rows] = self._resample(pred.x, w)

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
        """MMSE estimate x̂ (s, d) and covariance P (s, d, d) of ``rows``."""
        rows = np.asarray(rows, np.int64)
        return self.tracks.x[rows].copy(), self.tracks.P[rows].copy()

    def estimates_view(self) -> tuple[np.ndarray, np.ndarray]:
        """x (n, dim), P (n, dim, dim) of all tracks, not copied: read only."""
        return self.tracks.x, self.tracks.P

    def component_counts(self) -> np.ndarray:
        """One "component" (the cloud) per track."""
        return np.ones(len(self), np.int64)

    # ------------------------------------------------------------------ snapshots
    def to_snapshot(self) -> dict:
        """The random generator's state (the clouds are track-store columns): a restored
        tracker draws the same noise as the one that went on."""
        bits = self.rng.bit_generator
        return {"bit_generator": type(bits).__name__, "state": bits.state}

    def from_snapshot(self, snap) -> None:
        snap = mapping(snap, "density")
        name = entry(snap, "bit_generator", str)
        bits = type(self.rng.bit_generator)
        if name != bits.__name__:
            raise SnapshotError(f"bit generator {name[:40]!r}, this density uses {bits.__name__}")
        fresh = bits()
        try:
            fresh.state = mapping(snap.get("state"), "bit generator state")
        except (ValueError, TypeError, KeyError) as e:
            raise SnapshotError(f"{name} state: {e}") from None
        self.rng = np.random.Generator(fresh)
