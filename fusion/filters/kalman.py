"""Linear Kalman filter, batched over n states (tracks or mixture components).

Implements [thesis] §2.2 (2.21-2.27) with the Joseph-form covariance update of
[thesis] (5.14):

* predict:     x⁻ = F x,  P⁻ = F P Fᵀ + Q
* innovation:  ẑ = H x⁻,  S = H P⁻ Hᵀ + R
* gain:        K = P⁻ Hᵀ S⁻¹
* update:      x = x⁻ + K (z − ẑ),  P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ

Shapes: x (n, d); P (n, d, d); F, Q either (d, d) shared or (n, d, d) per state;
H (m, d); R (m, m) shared or (n, m, m); z (n, m). Units are whatever the model uses
(metres and m/s in skyfuse).
"""

from __future__ import annotations

import numba
import numpy as np

from .cholesky_kernels import cholesky_into, cholesky_solve_into


def predict(
    x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Predict states and covariances: x⁻ = F x, P⁻ = F P Fᵀ + Q."""
    x_pred = np.einsum("...ij,...j->...i", F, x)
    P_pred = F @ P @ F.swapaxes(-1, -2) + Q
    return x_pred, 0.5 * (P_pred + P_pred.swapaxes(-1, -2))


def innovation_covariance(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """S = H P Hᵀ + R, shape (n, m, m)."""
    S = H @ P @ H.T + R
    return 0.5 * (S + S.swapaxes(-1, -2))


def joseph_covariance(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(I − K H) P (I − K H)ᵀ + K R Kᵀ, symmetric and positive semi-definite by
    construction: P (n, d, d), K (n, d, k), H (k, d), R (k, k) or (n, k, k); one compiled
    loop over the n states (no (n, d, d) temporaries)."""
    P = np.asarray(P, dtype=np.float64)
    if P.ndim != 3:  # a single state
        return joseph_covariance(P[None], np.asarray(K)[None], H, R)[0]
    R = np.asarray(R, dtype=np.float64)
    if R.ndim != 3 or len(R) != len(P):
        R = np.broadcast_to(R, (len(P), *R.shape[-2:]))
    # C-contiguous float64 only: one compiled signature (loaded at start by
    # :func:`fusion.tracker.kernel_warmup.warm_up`, never compiled on a batch)
    c = np.ascontiguousarray
    return _joseph(c(P), c(K, dtype=np.float64), c(H, dtype=np.float64), c(R))


@numba.njit(cache=True, nogil=True)
def _joseph_into(P, K, H, R, out, A, T, KR):
    """out = (I − K H) P (I − K H)ᵀ + K R Kᵀ, symmetrised, for one state (A, T, KR:
    scratch (d, d), (d, d), (d, k))."""
    d, k = K.shape
    for i in range(d):  # A = I − K H
        for j in range(d):
            t = 1.0 if i == j else 0.0
            for m in range(k):
                t -= K[i, m] * H[m, j]
            A[i, j] = t
    for i in range(d):  # T = A P
        for j in range(d):
            t = 0.0
            for m in range(d):
                t += A[i, m] * P[m, j]
            T[i, j] = t
    for i in range(d):  # K R
        for j in range(k):
            t = 0.0
            for m in range(k):
                t += K[i, m] * R[m, j]
            KR[i, j] = t
    for i in range(d):  # T Aᵀ + K R Kᵀ, symmetrised
        for j in range(i + 1):
            u = 0.0
            v = 0.0
            for m in range(d):
                u += T[i, m] * A[j, m]
                v += T[j, m] * A[i, m]
            for m in range(k):
                u += KR[i, m] * K[j, m]
                v += KR[j, m] * K[i, m]
            out[i, j] = out[j, i] = 0.5 * (u + v)


@numba.njit(cache=True, nogil=True)
def _joseph(P, K, H, R):
    n, d, k = K.shape
    out = np.empty((n, d, d))
    A = np.empty((d, d))
    T = np.empty((d, d))
    KR = np.empty((d, k))
    for s in range(n):
        _joseph_into(P[s], K[s], H, R[s], out[s], A, T, KR)
    return out


@numba.njit(cache=True, nogil=True)
def _gain_into(P, H, S, K, L, B):
    """K = P Hᵀ S⁻¹ (d, k) for one state, by a solve rather than an inverse: for k = 2
    the closed form S⁻¹ = [[s₁₁, −s₀₁], [−s₀₁, s₀₀]] / (s₀₀ s₁₁ − s₀₁²), otherwise
    S = L Lᵀ and Kᵀ = S⁻¹ (P Hᵀ)ᵀ (L, B: scratch (k, k), (k, d)). False if S is not
    positive definite (k ≠ 2)."""
    d, k = K.shape
    for i in range(d):  # K ← P Hᵀ
        for j in range(k):
            t = 0.0
            for m in range(d):
                t += P[i, m] * H[j, m]
            K[i, j] = t
    if k == 2:
        a, b, c = S[0, 0], S[0, 1], S[1, 1]
        inv_det = 1.0 / (a * c - b * b)
        i00, i01, i11 = c * inv_det, -b * inv_det, a * inv_det
        for i in range(d):
            b0, b1 = K[i, 0], K[i, 1]
            K[i, 0] = b0 * i00 + b1 * i01
            K[i, 1] = b0 * i01 + b1 * i11
        return True
    if not cholesky_into(S, L):
        return False
    for i in range(d):
        for j in range(k):
            B[j, i] = K[i, j]
    cholesky_solve_into(L, B, B)
    for i in range(d):
        for j in range(k):
            K[i, j] = B[j, i]
    return True


@numba.njit(cache=True, nogil=True)
def update_into(x, P, H, S, nu, R, x_out, P_out, scratch):
    """One state's update with a known innovation ν (k,) and covariance S (k, k): x_out =
    x + K ν, P_out the Joseph covariance with R, K = P Hᵀ S⁻¹ (scratch: a tuple from
    :func:`update_scratch`); raises if S is not positive definite."""
    K, L, B, A, T, KR = scratch
    d, k = K.shape
    if not _gain_into(P, H, S, K, L, B):
        raise ValueError("innovation covariance not positive definite")
    for i in range(d):
        t = x[i]
        u = 0.0
        for j in range(k):
            u += K[i, j] * nu[j]
        x_out[i] = t + u
    _joseph_into(P, K, H, R, P_out, A, T, KR)


@numba.njit(cache=True, nogil=True)
def update_scratch(d, k):
    """Scratch arrays of :func:`update_into` for states of d entries and k measured."""
    z = np.zeros((k, k))
    return (np.empty((d, k)), z, np.empty((k, d)), np.empty((d, d)), np.empty((d, d)),
            np.empty((d, k)))  # fmt: skip


@numba.njit(cache=True, nogil=True)
def _update_pairs(x, P, H, S, nu, R):
    n, d = x.shape
    k = nu.shape[1]
    x_out = np.empty((n, d))
    P_out = np.empty((n, d, d))
    scratch = update_scratch(d, k)
    for s in range(n):
        update_into(x[s], P[s], H, S[s], nu[s], R[s], x_out[s], P_out[s], scratch)
    return x_out, P_out


def update_with_innovation(
    x: np.ndarray, P: np.ndarray, H: np.ndarray, S: np.ndarray, nu: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update of n predicted states x (n, d), P (n, d, d) whose innovations
    ν (n, k) and covariances S (n, k, k) are known (the gating computed them): K = P Hᵀ
    S⁻¹, x + K ν and the Joseph covariance with R (n, k, k) or (k, k); one compiled loop
    over the states (the Joseph step is :func:`joseph_covariance`'s)."""
    c = np.ascontiguousarray
    f = np.float64
    n = len(x)
    R = np.broadcast_to(np.asarray(R, dtype=f), (n, *np.shape(R)[-2:]))
    return _update_pairs(c(x, dtype=f), c(P, dtype=f), c(H, dtype=f), c(S, dtype=f),
                         c(nu, dtype=f), c(R))  # fmt: skip


def update(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, H: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Kalman update of n predicted states with n measurements.

    Returns ``(x_upd, P_upd, nu, S)`` where ``nu = z − H x`` is the innovation and ``S``
    its covariance (both useful for gating and likelihoods)."""
    S = innovation_covariance(P, H, R)
    nu = z - x @ H.T
    x_new, P_new = update_with_innovation(x, P, H, S, nu, R)
    return x_new, P_new, nu, S


def gaussian_log_likelihood(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """log N(nu; 0, S) for innovations nu (..., m) with covariances S (..., m, m)."""
    m = nu.shape[-1]
    L = np.linalg.cholesky(S)
    sol = np.linalg.solve(L, nu[..., None])[..., 0]
    d2 = np.einsum("...i,...i->...", sol, sol)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(-1)
    return -0.5 * (d2 + logdet + m * np.log(2.0 * np.pi))
