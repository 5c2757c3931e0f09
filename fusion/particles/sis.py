"""Sequential importance sampling with resampling on degeneracy (SIS; Arulampalam et al. 2002).

With the prior as proposal the weights recurse γ_k^i ∝ γ_{k−1}^i p(y_k | x_k^i);
a cloud is resampled only when N_eff = 1/Σγ² (ibid. eq. 51) falls below N_th. Weights are kept
in the linear domain between steps and combined in the log domain within a step.
"""

from __future__ import annotations

import numpy as np

from .model import StateSpaceModel
from .resampling import resample, take
from .sir import StepResult
from .weights import effective_sample_size, normalise_log_weights, weighted_moments


def resample_degenerate(
    x: np.ndarray, w: np.ndarray, threshold: float, rng: np.random.Generator, scheme: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Resample the clouds with N_eff < threshold (absolute particle count) in one call;
    returns (x, w, resampled mask). The others keep their particles and weights."""
    low = effective_sample_size(w) < threshold
    if not low.any():
        return x, w, low
    x, w = x.copy(), w.copy()
    idx = resample(w[low], rng, scheme)
    x[low] = take(x[low], idx)
    w[low] = 1.0 / w.shape[1]
    return x, w, low


def sis_step(
    model: StateSpaceModel,
    x: np.ndarray,
    w: np.ndarray,
    y: np.ndarray,
    k: int,
    rng: np.random.Generator,
    threshold: float,
    scheme: str = "systematic",
) -> StepResult:
    """One SIS step of clouds x (n, N, d) with weights w (n, N); resample where
    N_eff < ``threshold`` particles (e.g. N/2)."""
    xp = model.propagate(x, k, rng)
    with np.errstate(divide="ignore"):
        log_w = np.log(w) + model.log_likelihood(xp, y, k)
    w = normalise_log_weights(log_w)
    mean, cov = weighted_moments(xp, w)
    xr, wr, low = resample_degenerate(xp, w, threshold, rng, scheme)
    return StepResult(xr, wr, mean, cov, low)
