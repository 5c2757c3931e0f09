"""The state-space model interface of the generic particle-filter steps (Arulampalam et al. 2002).

A model acts on many clouds at once: particles x (n, N, d), one observation per cloud
y (n, m). ``k`` is the time index of the step being taken (k = 1, 2, …), needed by
time-varying models such as the scalar benchmark of :mod:`.nonlinear_benchmark`.

* ``propagate(x, k, rng)`` draws x_k ~ p(x_k | x_{k−1}) for every particle (the prior
  proposal of SIR/SIS).
* ``mean_transition(x, k)`` = μ = E[x_k | x_{k−1}] (the APF look-ahead point).
* ``log_likelihood(x, y, k)`` = log p(y_k | x_k), shape (n, N).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np


class StateSpaceModel(Protocol):
    def propagate(self, x: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray: ...

    def mean_transition(self, x: np.ndarray, k: int) -> np.ndarray: ...

    def log_likelihood(self, x: np.ndarray, y: np.ndarray, k: int) -> np.ndarray: ...
