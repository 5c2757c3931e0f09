"""The noise terms (O1-O2) of the out-of-sequence update (:mod:`.oosm`, Bar-Shalom 2002
A1 in its prior/posterior form), one track state at a time, compiled with numba: per
state a handful of d × d products and three Cholesky factorisations (d ≤ 10) whose
per-matrix outcome decides between A1 and the independent-noise fallback. In NumPy the
same took three batched ``eigvalsh``, an ``inv`` and a ``solve``, whose LAPACK
per-matrix overhead was most of the out-of-sequence pass on coarse sector batches.

For a state with posterior P = P(k|k), prior P⁻ = P(k|k−1) (both symmetric positive
definite, else the fallback), process noise Q = Q(Δ) and A = (P⁻)⁻¹ Q:

    P_xv = P A,   P_vv = sym(Q − Aᵀ (P⁻ − P) A),   correction = Aᵀ (x̂(k|k) − x̂(k|k−1))

(Q P⁻⁻¹ = Aᵀ since Q and P⁻ are symmetric). A1 is kept where its conditional noise
covariance P_vv − P_xvᵀ P⁻¹ P_xv is positive semi-definite to −10⁻⁶ × the largest
|Q_ii|: the Cholesky factorisation of that matrix plus 10⁻⁶ max|Q_ii| I succeeds.
Units: m, m/s (the state layout of the model).
"""

from __future__ import annotations

import numba
import numpy as np
from skyfuse.fusion.filters.cholesky_kernels import cholesky_into, cholesky_solve_into

PSD_TOLERANCE = 1e-6
"""Relative tolerance (to the largest |Q_ii|) of the A1 conditional noise PSD test."""


@numba.njit(cache=True, nogil=True)
def _symmetrised_into(A: np.ndarray, S: np.ndarray) -> None:
    d = A.shape[0]
    for i in range(d):
        for j in range(d):
            S[i, j] = 0.5 * (A[i, j] + A[j, i])


@numba.njit(cache=True, nogil=True)
def _a1_row(x, P, Q, x_prior, P_prior, Pxv, Pvv, corr, W) -> bool:
    """A1 terms of one state into Pxv, Pvv, corr (d × d, d × d, d); False where the
    fallback applies (then the outputs are not written). W: (6, d, d) scratch."""
    d = P.shape[0]
    S, Lp, L, A, Y, C = W[0], W[1], W[2], W[3], W[4], W[5]
    _symmetrised_into(P_prior, S)
    if not cholesky_into(S, Lp):
        return False
    _symmetrised_into(P, S)
    if not cholesky_into(S, L):
        return False
    cholesky_solve_into(Lp, Q, A)  # A = (P⁻)⁻¹ Q
    for i in range(d):  # Y = (P⁻ − P) A
        for j in range(d):
            t = 0.0
            for m in range(d):
                t += (P_prior[i, m] - P[i, m]) * A[m, j]
            Y[i, j] = t
    for i in range(d):  # S = Q − Aᵀ Y (then symmetrised: P_vv);  C = P A (P_xv)
        for j in range(d):
            t, u = Q[i, j], 0.0
            for m in range(d):
                t -= A[m, i] * Y[m, j]
                u += P[i, m] * A[m, j]
            S[i, j] = t
            C[i, j] = u
    _symmetrised_into(S, Pvv)
    cholesky_solve_into(L, C, Y)  # Y = P⁻¹ P_xv
    scale = 1e-300
    for i in range(d):
        scale = max(scale, abs(Q[i, i]))
    for i in range(d):  # S = P_vv − P_xvᵀ P⁻¹ P_xv + tol I
        for j in range(d):
            t = Pvv[i, j]
            for m in range(d):
                t -= C[m, i] * Y[m, j]
            S[i, j] = t
    for i in range(d):
        for j in range(i):
            S[i, j] = S[j, i] = 0.5 * (S[i, j] + S[j, i])
        S[i, i] += PSD_TOLERANCE * scale
    if not cholesky_into(S, Lp):
        return False
    Pxv[:, :] = C
    for i in range(d):
        t = 0.0
        for m in range(d):
            t += A[m, i] * (x[m] - x_prior[m])
        corr[i] = t
    return True


@numba.njit(cache=True, nogil=True)
def a1_terms_into(x, P, Q, x_prior, P_prior, rows, Pxv, Pvv, corr) -> None:
    """A1 terms of the states ``rows`` written into Pxv (n, d, d), Pvv, corr (n, d),
    which hold the fallback (0, Q, 0) beforehand and keep it where A1 does not apply."""
    d = P.shape[1]
    W = np.zeros((6, d, d))
    pv = np.empty((d, d))
    xv = np.empty((d, d))
    c = np.empty(d)
    for r in rows:
        if _a1_row(x[r], P[r], Q[r], x_prior[r], P_prior[r], xv, pv, c, W):
            Pxv[r] = xv
            Pvv[r] = pv
            corr[r] = c
