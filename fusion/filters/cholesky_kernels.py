"""Per-matrix Cholesky factorisation of small symmetric matrices, compiled with numba
(``cache=True``): the loop over a batch of d × d matrices (d ≤ 10: innovation
covariances, state covariances of one mode) that NumPy cannot express with a
per-matrix outcome. ``np.linalg.cholesky`` of a batch raises for the whole batch when
one matrix is not positive definite, and ``np.linalg.eigvalsh`` costs ≈ 1.3 µs per 5 × 5
matrix in LAPACK's per-matrix overhead, against ≈ 0.05 µs here.

A = L Lᵀ with L lower triangular (Cholesky–Banachiewicz):

    L_jj = √(A_jj − Σ_{m<j} L_jm²),   L_ij = (A_ij − Σ_{m<j} L_im L_jm) / L_jj  (i > j),

which succeeds (every radicand > 0) exactly when the symmetric A is positive definite,
up to rounding. Only the lower triangle of A is read, i.e. A is taken as symmetric; a
caller with a possibly asymmetric A passes (A + Aᵀ)/2. Solves with L by forward and back
substitution. Units are those of the inputs.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def cholesky_into(A: np.ndarray, L: np.ndarray) -> bool:
    """Factor the d × d symmetric A into the lower triangle of L (d × d, its upper
    triangle is left as it was); False (L partly written) if A is not positive definite
    or not finite."""
    d = A.shape[0]
    for j in range(d):
        s = A[j, j]
        for m in range(j):
            s -= L[j, m] * L[j, m]
        if not s > 0.0 or not np.isfinite(s):  # also NaN
            return False
        ljj = np.sqrt(s)
        L[j, j] = ljj
        for i in range(j + 1, d):
            t = A[i, j]
            for m in range(j):
                t -= L[i, m] * L[j, m]
            L[i, j] = t / ljj
    return True


@numba.njit(cache=True, nogil=True)
def cholesky_solve_into(L: np.ndarray, B: np.ndarray, X: np.ndarray) -> None:
    """X = A⁻¹ B (d × k) for A = L Lᵀ: L y = B forward, Lᵀ X = y backward (X may be B)."""
    d, k = B.shape
    for c in range(k):
        for i in range(d):
            t = B[i, c]
            for m in range(i):
                t -= L[i, m] * X[m, c]
            X[i, c] = t / L[i, i]
        for i in range(d - 1, -1, -1):
            t = X[i, c]
            for m in range(i + 1, d):
                t -= L[m, i] * X[m, c]
            X[i, c] = t / L[i, i]


@numba.njit(cache=True, nogil=True)
def _positive_definite(A: np.ndarray) -> np.ndarray:
    n, d = A.shape[0], A.shape[1]
    out = np.zeros(n, np.bool_)
    L = np.empty((d, d))
    S = np.empty((d, d))
    for r in range(n):
        for i in range(d):
            for j in range(d):
                S[i, j] = 0.5 * (A[r, i, j] + A[r, j, i])
        out[r] = cholesky_into(S, L)
    return out


def positive_definite(A: np.ndarray) -> np.ndarray:
    """(n,) whether each of n matrices A (n, d, d) is finite and, symmetrised as
    (A + Aᵀ)/2, positive definite."""
    A = np.ascontiguousarray(A, dtype=np.float64)
    if A.ndim != 3 or A.shape[1] != A.shape[2]:
        raise ValueError(f"matrices of shape {A.shape}: expected (n, d, d)")
    if len(A) == 0 or A.shape[1] == 0:
        return np.ones(len(A), bool)
    return _positive_definite(A)
