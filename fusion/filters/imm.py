"""Interacting Multiple Model filter, batched over tracks (spec 01 §5, 004 eq. 15-21).

One cycle for n tracks and r mode filters with transition probabilities p_ij
(``tpm[i, j]`` = P(mode j at k | mode i at k−1)):

1. mixing (eq. 15-17): c_j = Σ_i p_ij μ_i; μ_{i|j} = p_ij μ_i / c_j;
   x̂_j⁰ = Σ_i μ_{i|j} x̂_i;  P_j⁰ = Σ_i μ_{i|j} [P_i + (x̂_i − x̂_j⁰)(x̂_i − x̂_j⁰)ᵀ]
   (the source prints x_i⁰ in the spread term; it is x̂_j⁰);
2. mode-matched prediction and update of each filter from (x̂_j⁰, P_j⁰);
3. likelihood Λ_j = N(ν_j; 0, S_j) (eq. 18), μ_j = Λ_j c_j / Σ_l Λ_l c_l (eq. 19);
4. output x̂ = Σ_j μ_j x̂_j, P = Σ_j μ_j [P_j + (x̂_j − x̂)(x̂_j − x̂)ᵀ] (eq. 20-21).

Mixing and output are done in a common state format: the mode filters' own format when
they all share one, else the Singer layout with the conversions of spec 01 §4
(:mod:`fusion.models.conversions`). :meth:`IMM.predict` performs step 1 and the
prediction, leaving the predicted mode probabilities c in ``state.mu``; a track that is
not updated keeps them (missed detection).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models import ConstantVelocity, CoordinatedTurn, Singer
from .gaussian_state import GaussianState
from .imm_interaction import interact
from .measurement_models import PolarMeasurement, wrap_angle
from .model_filter import (
    ConvertedMeasurementKF,
    ModelFilter,
    common_one_point,
    common_two_point,
)
from .moment_matching import moment_match_rows

G0 = 9.80665


@dataclass
class IMMState:
    """Per-mode means x[j] (n, d_j), covariances P[j] (n, d_j, d_j); mode probabilities
    mu (n, r)."""

    x: list[np.ndarray]
    P: list[np.ndarray]
    mu: np.ndarray

    def __len__(self) -> int:
        return self.mu.shape[0]

    def take(self, idx) -> IMMState:
        return IMMState([a[idx] for a in self.x], [a[idx] for a in self.P], self.mu[idx])

    def put(self, idx, other: IMMState) -> None:
        for j in range(len(self.x)):
            self.x[j][idx] = other.x[j]
            self.P[j][idx] = other.P[j]
        self.mu[idx] = other.mu

    @staticmethod
    def concat(states: list[IMMState]) -> IMMState:
        r = len(states[0].x)
        return IMMState(
            [np.concatenate([s.x[j] for s in states]) for j in range(r)],
            [np.concatenate([s.P[j] for s in states]) for j in range(r)],
            np.concatenate([s.mu for s in states]),
        )

    def copy(self) -> IMMState:
        return IMMState([a.copy() for a in self.x], [a.copy() for a in self.P], self.mu.copy())


class IMM:
    """IMM over mode filters (:class:`ModelFilter`) with transition matrix ``tpm`` (r, r)."""

    def __init__(self, filters: list[ModelFilter], tpm, name: str = "imm") -> None:
        self.filters = list(filters)
        r = len(self.filters)
        tpm = np.asarray(tpm, float)
        if tpm.shape != (r, r):
            raise ValueError(f"tpm has shape {tpm.shape}: must be ({r}, {r}) for {r} modes")
        if (tpm < 0).any() or not np.allclose(tpm.sum(axis=1), 1.0, atol=1e-9):
            raise ValueError(f"tpm = {tpm.tolist()}: rows must be probabilities summing to 1")
        self.tpm = tpm
        self.name = name
        labels = {f.labels for f in self.filters}
        self.native_common = len(labels) == 1
        self.labels = self.filters[0].labels if self.native_common else None
        if not self.native_common:
            nd = self.filters[0].model.ndim
            self.labels = tuple(
                lab
                for ax in (("x", "vx", "ax"), ("y", "vy", "ay"), ("z", "vz", "az"))[:nd]
                for lab in ax
            )
        self.position_index = tuple(
            self.labels.index(a) for a in ("x", "y", "z") if a in self.labels
        )

    @property
    def r(self) -> int:
        return len(self.filters)

    # --- format helpers -----------------------------------------------------------------
    def _to_common(self, j, x, P):
        return (x, P) if self.native_common else self.filters[j].to_common(x, P)

    def _from_common(self, j, x, P):
        return (x, P) if self.native_common else self.filters[j].from_common(x, P)

    def initiate_common(self, xc, Pc, mu0=None) -> IMMState:
        n = xc.shape[0]
        mu0 = np.full(self.r, 1.0 / self.r) if mu0 is None else np.asarray(mu0, float)
        xs, Ps = zip(*(self._from_common(j, xc, Pc) for j in range(self.r)), strict=True)
        return IMMState(list(xs), list(Ps), np.broadcast_to(mu0, (n, self.r)).copy())

    def initiate(self, z, R, *, velocity_sigma=300.0, acceleration_sigma=10.0, mu0=None):
        if self.native_common:
            st = self.filters[0].initiate(
                z, R, velocity_sigma=velocity_sigma, acceleration_sigma=acceleration_sigma
            )
            return self.initiate_common(st.x, st.P, mu0)
        xc, Pc = common_one_point(
            z, R, velocity_sigma, acceleration_sigma, self.filters[0].model.ndim
        )
        return self.initiate_common(xc, Pc, mu0)

    def initiate_two_point(self, z1, R1, z2, R2, dt, *, acceleration_sigma=10.0, mu0=None):
        if self.native_common:
            st = self.filters[0].initiate_two_point(
                z1, R1, z2, R2, dt, acceleration_sigma=acceleration_sigma
            )
            return self.initiate_common(st.x, st.P, mu0)
        xc, Pc = common_two_point(
            z1, R1, z2, R2, dt, acceleration_sigma, self.filters[0].model.ndim
        )
        return self.initiate_common(xc, Pc, mu0)

    # --- the cycle ------------------------------------------------------------------------
    def mix(self, state: IMMState):
        """Step 1 (eq. 15-17, :func:`fusion.filters.imm_interaction.interact`): mixed
        initial conditions per mode and c (n, r)."""
        return interact(state.mu, self.tpm, state.x, state.P, [f.model for f in self.filters])

    def predict(self, state: IMMState, dt) -> IMMState:
        x0, P0, c = self.mix(state)
        xs, Ps = [], []
        for j, f in enumerate(self.filters):
            s = f.predict(GaussianState(x0[j], P0[j]), dt)
            xs.append(s.x)
            Ps.append(s.P)
        return IMMState(xs, Ps, c)

    def predict_measurement(self, state: IMMState, R):
        """Mode-mixed predicted measurement (moment-matched over c = state.mu):
        ẑ (n, m), S (n, m, m); and the per-mode lists (for per-model association)."""
        per = [
            f.predict_measurement(GaussianState(state.x[j], state.P[j]), R)
            for j, f in enumerate(self.filters)
        ]
        zs = np.stack([p[0] for p in per], axis=1)
        Ss = np.stack([p[1] for p in per], axis=1)
        if any(isinstance(f.measurement, PolarMeasurement) for f in self.filters):
            # polar: average the azimuths around the first mode's (no 2π jumps)
            zs[..., 1] = zs[:, :1, 1] + wrap_angle(zs[..., 1] - zs[:, :1, 1])
        zhat, S = moment_match_rows(state.mu, zs, Ss)
        return zhat, S, per

    def update(self, state: IMMState, z, R):
        """Steps 2-3: update every mode with z (n, m), R; returns (state, log-likelihood (n,))."""
        xs, Ps, ll = [], [], []
        for j, f in enumerate(self.filters):
            s, _, _, lj = f.update(GaussianState(state.x[j], state.P[j]), z, R)
            xs.append(s.x)
            Ps.append(s.P)
            ll.append(lj)
        L = np.stack(ll, axis=1) + np.log(np.maximum(state.mu, 1e-300))
        top = L.max(axis=1, keepdims=True)
        w = np.exp(L - top)
        total = w.sum(axis=1, keepdims=True)
        return IMMState(xs, Ps, w / total), (top + np.log(total))[:, 0]

    def estimate(self, state: IMMState) -> GaussianState:
        """Step 4 (eq. 20-21): combined estimate in the common format."""
        common = [self._to_common(j, state.x[j], state.P[j]) for j in range(self.r)]
        xs = np.stack([cx for cx, _ in common], axis=1)
        Ps = np.stack([cP for _, cP in common], axis=1)
        return GaussianState(*moment_match_rows(state.mu, xs, Ps))

    def position(self, state: IMMState) -> np.ndarray:
        return self.estimate(state).x[:, list(self.position_index)]


SOURCE_TPM_IMM2 = ((0.95, 0.05), (0.9, 0.1))
"""003 eq. 13 as printed: p11 = 0.95, p12 = 0.05, p21 = 0.9, p22 = 0.1."""
TYPICAL_TPM_IMM2 = ((0.95, 0.05), (0.1, 0.9))
"""The usual choice with a persistent manoeuvre mode, p22 = 0.9."""


def imm2_pcwpa(
    tpm=SOURCE_TPM_IMM2, sigma1: float = G0 / 2, sigma2: float = 2 * G0, ndim: int = 2
) -> IMM:
    """003's two-model IMM: two PCWPA (CV) filters with Q = G σ_j² Gᵀ, σ₁ = g/2 (gentle),
    σ₂ = 2g (sharp manoeuvres), converted-measurement updates; ``tpm`` a parameter."""
    return IMM(
        [
            ConvertedMeasurementKF(ConstantVelocity(q=sigma1**2, ndim=ndim), "cv-gentle"),
            ConvertedMeasurementKF(ConstantVelocity(q=sigma2**2, ndim=ndim), "cv-sharp"),
        ],
        tpm,
        name="imm2",
    )


def imm3_cv_singer_ct(
    tpm=((0.90, 0.05, 0.05), (0.05, 0.90, 0.05), (0.05, 0.05, 0.90)),
    *,
    q_cv: float = (G0 / 2) ** 2,
    singer_tau: float = 10.0,
    singer_sigma_m: float = 2 * G0,
    ct_sigma_a: float = 2.0,
    ct_sigma_omega: float = 0.02,
    ndim: int = 2,
    q_vertical: float = 1.0,
) -> IMM:
    """004's three-model IMM (CV + Singer + coordinated turn) mixed in the common Singer
    format with the state conversions of spec 01 §4. ``ndim = 3`` adds the altitude
    channel: CV and Singer in 3-D, the turn model with a nearly-constant vertical
    velocity (white acceleration variance ``q_vertical``, m²/s⁴)."""
    if ndim not in (2, 3):
        raise ValueError(f"ndim = {ndim}: must be 2 or 3")
    vertical = ndim == 3
    cv = ConstantVelocity(q=q_cv, ndim=ndim, q_vertical=q_vertical if vertical else None)
    singer = Singer(tau=singer_tau, sigma_m=singer_sigma_m, ndim=ndim)
    ct = CoordinatedTurn(ct_sigma_a, ct_sigma_omega, vertical=vertical, q_vertical=q_vertical)
    return IMM(
        [
            ConvertedMeasurementKF(cv, "cv"),
            ConvertedMeasurementKF(singer, "singer"),
            ConvertedMeasurementKF(ct, "ct"),
        ],
        tpm,
        name="imm3",
    )
