"""Auxiliary particle filter (APF, Pitt & Shephard 1999; Arulampalam et al. 2002, Algorithm 5).

One step on clouds x (n, N, d) with weights γ (n, N):

1. look-ahead points μ^i = E[x_k | x_{k−1}^i] (model.mean_transition);
2. first-stage weights λ_i ∝ γ^i p(y_k | μ^i); draw ancestor indices i_j from λ
   (default systematic resampling);
3. propagate x_k^j ~ p(x_k | x_{k−1}^{i_j});
4. second-stage weights γ^j ∝ p(y_k | x_k^j) / p(y_k | μ^{i_j}), normalised;
5. MMSE mean and covariance of the weighted cloud.

The look-ahead moves particles towards the observation before propagation, which helps
when the likelihood is peaked relative to the prior.
"""

from __future__ import annotations

import numpy as np

from .model import StateSpaceModel
from .resampling import resample, take
from .sir import StepResult
from .weights import normalise_log_weights, weighted_moments


def apf_step(
    model: StateSpaceModel,
    x: np.ndarray,
    w: np.ndarray,
    y: np.ndarray,
    k: int,
    rng: np.random.Generator,
    scheme: str = "systematic",
) -> StepResult:
    """One auxiliary-particle-filter step; returns the weighted cloud after stage 2."""
    mu = model.mean_transition(x, k)
    log_first = model.log_likelihood(mu, y, k)
    with np.errstate(divide="ignore"):
        lam = normalise_log_weights(np.log(w) + log_first)
    idx = resample(lam, rng, scheme)
    xp = model.propagate(take(x, idx), k, rng)
    log_w = model.log_likelihood(xp, y, k) - np.take_along_axis(log_first, idx, axis=1)
    w_new = normalise_log_weights(log_w)
    mean, cov = weighted_moments(xp, w_new)
    return StepResult(xp, w_new, mean, cov, np.ones(len(w), bool))
