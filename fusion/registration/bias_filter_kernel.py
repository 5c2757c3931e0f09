"""Compiled gate and information update of :class:`~.bias_filter.BiasFilter` for one batch
of pairs (equations (1)–(2) of :mod:`.bias_filter`; normalised units s = β/σ_0).

For every pair k of radars (a, b) the row block of the stacked measurement matrix is
H_k = [… H_{a,k} diag(σ_0) … −H_{b,k} diag(σ_0) …] (2 × 4n), with the columns of the fixed
components (reference radars, components not estimated) zero. The pair is *informative*
when H_k ≠ 0 and *used* when also

    d²_k = ν_kᵀ S_k⁻¹ ν_k ≤ gate,   ν_k = y_k − H_k s,   S_k = H_k P H_kᵀ + W_k,

(the gating's 2 × 2 closed form,
:func:`~fusion.association.gating_kernels.statistics_2x2`: a non-positive-definite S_k
gives d² = ∞). Over the f free components (indices ``idx``) the used pairs update the
information form (Bar-Shalom, Li & Kirubarajan 2001, eq. 7.2.1-3):

    Λ⁺ = P_f⁻¹ + Σ_k H_kᵀ W_k⁻¹ H_k,   η⁺ = P_f⁻¹ s_f + Σ_k H_kᵀ W_k⁻¹ y_k,
    P_f ← sym((Λ⁺)⁻¹),   s_f ← (Λ⁺)⁻¹ η⁺.

The 2 × 2 inverses are closed forms. One call replaces ≈ 25 NumPy calls whose per-call
cost was most of the update at a sector batch's few tens of pairs (docs/performance.md).
"""

from __future__ import annotations

import numba
import numpy as np
from skyfuse.fusion.association.gating_kernels import statistics_2x2


@numba.njit(cache=True, nogil=True)
def _pair_rows(h, j, free, sigma0, HA, HB, a, b) -> bool:
    """Fill h (2, N) with pair j's row block of H; True if any entry is non-zero."""
    h[:] = 0.0
    for r in range(2):
        for c in range(4):
            h[r, 4 * a[j] + c] += HA[j, r, c] * sigma0[c]
            h[r, 4 * b[j] + c] -= HB[j, r, c] * sigma0[c]
    informative = False
    for i in range(h.shape[1]):
        for r in range(2):
            if not free[i]:
                h[r, i] = 0.0
            elif h[r, i] != 0.0:
                informative = True
    return informative


@numba.njit(cache=True, nogil=True)
def _d2(h, s, P, y, W) -> float:
    """ν_kᵀ S_k⁻¹ ν_k for one pair's h (2, N), y (2,), W (2, 2); ∞ if S is not PD."""
    nu = y - h @ s
    S = h @ P @ h.T + W
    return statistics_2x2(S, nu)[0]


@numba.njit(cache=True, nogil=True)
def gate_and_update(s, P, free, sigma0, y, W, HA, HB, a, b, gate, used, rejected) -> int:
    """Gate the k pairs and update s (N,), P (N, N) in place (module docstring); adds the
    pairs used to ``used`` (per radar of a and of b) and the informative pairs gated out
    to ``rejected`` (per radar a). Returns the number of pairs used."""
    k, N = len(y), len(s)
    idx = np.flatnonzero(free)
    f = len(idx)
    h = np.zeros((2, N))
    info = np.zeros((f, f))
    eta = np.zeros(f)
    n_ok = 0
    for j in range(k):
        if not _pair_rows(h, j, free, sigma0, HA, HB, a, b):
            continue
        if not _d2(h, s, P, y[j], W[j]) <= gate:
            rejected[a[j]] += 1
            continue
        n_ok += 1
        used[a[j]] += 1
        used[b[j]] += 1
        w00, w01, w11 = W[j, 0, 0], W[j, 0, 1], W[j, 1, 1]
        inv_det = 1.0 / (w00 * w11 - w01 * w01)
        i00, i01, i11 = w11 * inv_det, -w01 * inv_det, w00 * inv_det
        for p in range(f):  # HᵀW⁻¹ row p, then its products with H and y
            g0 = h[0, idx[p]] * i00 + h[1, idx[p]] * i01
            g1 = h[0, idx[p]] * i01 + h[1, idx[p]] * i11
            eta[p] += g0 * y[j, 0] + g1 * y[j, 1]
            for q in range(f):
                info[p, q] += g0 * h[0, idx[q]] + g1 * h[1, idx[q]]
    if n_ok == 0:
        return 0
    Pf = np.empty((f, f))
    sf = np.empty(f)
    for p in range(f):
        sf[p] = s[idx[p]]
        for q in range(f):
            Pf[p, q] = P[idx[p], idx[q]]
    info += np.linalg.inv(Pf)
    eta += np.linalg.solve(Pf, sf)
    Pn = np.linalg.inv(info)
    s_new = Pn @ eta
    for p in range(f):
        s[idx[p]] = s_new[p]
        for q in range(f):
            P[idx[p], idx[q]] = 0.5 * (Pn[p, q] + Pn[q, p])
    return n_ok
