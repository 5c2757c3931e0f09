"""Per-mode likelihoods of the gated (component, plot) pairs of the IMM density, one
compiled loop (numba, ``cache=True``; [Dikić] eq. 18-19, [thesis] (5.7)).

For pair q = (component c, plot i) and every mode j of c:

    ν_qj = z_i − ŷ_cj,   S_qj = sym(H_j P_cj H_jᵀ + R_i),   sym(A) = (A + Aᵀ)/2,
    log N_qj = −(ν_qjᵀ S_qj⁻¹ ν_qj + ln det S_qj + k ln 2π)/2,
    mix_q = Σ_j μ_cj N_qj   (the mode-mixed likelihood, before the 1/P_G of 4.17).

d² and ln det S by the gating's own per-pair algebra
(:func:`fusion.association.gating_kernels.statistics_2x2` for k = 2, the Cholesky form
otherwise; an S that is not positive definite gets N = 0). The NumPy form of the same
takes a dozen (P, r, k, k) array operations per batch; units are those of the inputs
(m, m²).
"""

from __future__ import annotations

import numba
import numpy as np
from skyfuse.fusion.association.gating_kernels import statistics_2x2, statistics_cholesky

LOG_2PI = float(np.log(2.0 * np.pi))


@numba.njit(cache=True, nogil=True)
def mode_pair_likelihoods(pc, pp, y, HPH, z, R, mu):
    """(ν (P, r, k), S (P, r, k, k), log N (P, r), mix (P,)) of the pairs (pc, pp):
    y (C, r, k), HPH (C, r, k, k) per component and mode, z (m, k), R (m, k, k),
    μ (C, r)."""
    n = len(pc)
    r, k = y.shape[1], y.shape[2]
    nu = np.empty((n, r, k))
    S = np.empty((n, r, k, k))
    log_n = np.empty((n, r))
    mix = np.zeros(n)
    L = np.zeros((k, k))
    w = np.empty(k)
    for q in range(n):
        c, i = pc[q], pp[q]
        for j in range(r):
            for a in range(k):
                nu[q, j, a] = z[i, a] - y[c, j, a]
            for a in range(k):
                for b in range(k):
                    s_ab = HPH[c, j, a, b] + R[i, a, b]
                    s_ba = HPH[c, j, b, a] + R[i, b, a]
                    S[q, j, a, b] = 0.5 * (s_ab + s_ba)
            if k == 2:
                d2, logdet = statistics_2x2(S[q, j], nu[q, j])
            else:
                d2, logdet = statistics_cholesky(S[q, j], nu[q, j], L, w)
            log_n[q, j] = -0.5 * (d2 + logdet + k * LOG_2PI) if d2 < np.inf else -np.inf
            mix[q] += mu[c, j] * np.exp(log_n[q, j])
    return nu, S, log_n, mix
