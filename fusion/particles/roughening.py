"""Roughening (jitter) after resampling (Gordon, Salmond & Smith 1993 [LIT]; the
form of that paper: the PF thesis we follow names roughening without one).

Each component d of every particle gets independent N(0, σ_d²) noise with
σ_d = K · E_d · N^{−1/D}, E_d the spread (max − min) of component d in that cloud, N the
number of particles and D the state dimension; K is a tuning constant (0.2 in the
original paper). It restores diversity lost to duplicated ancestors when the process
noise is small. Clouds x (n, N, D); the spread is taken per cloud.
"""

from __future__ import annotations

import numpy as np


def roughening_sigma(x: np.ndarray, K: float = 0.2) -> np.ndarray:
    """σ (n, D) = K E_d N^{−1/D} per cloud."""
    _, N, D = x.shape
    spread = x.max(axis=1) - x.min(axis=1)
    return K * spread * N ** (-1.0 / D)


def roughen(x: np.ndarray, rng: np.random.Generator, K: float = 0.2) -> np.ndarray:
    """Particles (n, N, D) with roughening noise added (a new array)."""
    if K <= 0:
        return x
    sigma = roughening_sigma(x, K)
    return x + sigma[:, None, :] * rng.standard_normal(x.shape)
