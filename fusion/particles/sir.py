"""Sampling–importance–resampling (SIR, bootstrap filter; Gordon et al. 1993).

One step on n clouds of N equally weighted particles (the output of the previous step):

1. x_k^i = f(x_{k−1}^i, ω^i) — propagate with the prior (model.propagate);
2. γ_i ∝ p(y_k | x_k^i), normalised (model.log_likelihood, log-sum-exp);
3. MMSE mean and covariance from the weighted cloud, *before* resampling
   (lower variance than after, [IMPL]);
4. resample N with replacement (default systematic), weights 1/N.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import StateSpaceModel
from .resampling import resample, take
from .weights import normalise_log_weights, weighted_moments


@dataclass
class StepResult:
    """Particles (n, N, d) and weights (n, N) after the step; MMSE mean (n, d) and
    covariance (n, d, d); ``resampled`` (n,) which clouds were resampled."""

    x: np.ndarray
    w: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    resampled: np.ndarray


def sir_step(
    model: StateSpaceModel,
    x: np.ndarray,
    y: np.ndarray,
    k: int,
    rng: np.random.Generator,
    scheme: str = "systematic",
) -> StepResult:
    """One SIR step of clouds x (n, N, d) with observations y (n, m) at time index k."""
    xp = model.propagate(x, k, rng)
    w = normalise_log_weights(model.log_likelihood(xp, y, k))
    mean, cov = weighted_moments(xp, w)
    idx = resample(w, rng, scheme)
    n, N = w.shape
    return StepResult(take(xp, idx), np.full((n, N), 1.0 / N), mean, cov, np.ones(n, bool))
