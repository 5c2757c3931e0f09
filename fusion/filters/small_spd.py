"""The largest eigenvalue of small symmetric matrices (n, k, k), batched: the reach
gate's widest σ of the IMM.

For k = 2 the closed form λ_max = (a + c)/2 + √(((a − c)/2)² + b²) replaces LAPACK's
``eigvalsh``, whose per-matrix overhead costs several times the arithmetic over the tens
of rows of one sector batch; other sizes use LAPACK. The 2 × 2 closed forms of d², ln det
S and the gain live with their loops (:mod:`fusion.association.gating_kernels`,
:mod:`fusion.filters.kalman`). Units are those of the inputs.
"""

from __future__ import annotations

import numpy as np


def largest_eigenvalue(C: np.ndarray) -> np.ndarray:
    """λ_max (n,) of symmetric C (n, k, k): for k = 2 the closed form
    (a + c)/2 + √(((a − c)/2)² + b²), otherwise LAPACK's ``eigvalsh``."""
    if C.shape[-1] == 2:
        a, b, c = C[:, 0, 0], C[:, 0, 1], C[:, 1, 1]
        return 0.5 * (a + c) + np.hypot(0.5 * (a - c), b)
    if C.shape[-1] == 1:
        return C[:, 0, 0].copy()
    return np.linalg.eigvalsh(C)[:, -1]
