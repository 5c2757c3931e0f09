"""Linear Kalman filter, batched over n states (tracks or mixture components).

Implements spec 02 §2 (thesis 2.21-2.27) with the Joseph-form covariance update of
spec 02 §7 step 10 (5.14):

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

from .small_spd import right_solve


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


def gain(P: np.ndarray, H: np.ndarray, S: np.ndarray) -> np.ndarray:
    """K = P Hᵀ S⁻¹, shape (n, d, m), computed by a solve rather than an inverse."""
    PHt = P @ H.T  # (n, d, m)
    # K S = P Hᵀ  ⇔  Sᵀ Kᵀ = (P Hᵀ)ᵀ ; S is symmetric (closed form for m = 2).
    if PHt.ndim == 3 and np.ndim(S) == 3:
        return right_solve(PHt, S)
    return np.swapaxes(np.linalg.solve(S, PHt.swapaxes(-1, -2)), -1, -2)


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
def _joseph(P, K, H, R):
    n, d, k = K.shape
    out = np.empty((n, d, d))
    A = np.empty((d, d))
    T = np.empty((d, d))
    KR = np.empty((d, k))
    for s in range(n):
        for i in range(d):  # A = I − K H
            for j in range(d):
                t = 1.0 if i == j else 0.0
                for m in range(k):
                    t -= K[s, i, m] * H[m, j]
                A[i, j] = t
        for i in range(d):  # T = A P
            for j in range(d):
                t = 0.0
                for m in range(d):
                    t += A[i, m] * P[s, m, j]
                T[i, j] = t
        for i in range(d):  # K R
            for j in range(k):
                t = 0.0
                for m in range(k):
                    t += K[s, i, m] * R[s, m, j]
                KR[i, j] = t
        for i in range(d):  # T Aᵀ + K R Kᵀ, symmetrised
            for j in range(i + 1):
                u = 0.0
                v = 0.0
                for m in range(d):
                    u += T[i, m] * A[j, m]
                    v += T[j, m] * A[i, m]
                for m in range(k):
                    u += KR[i, m] * K[s, j, m]
                    v += KR[j, m] * K[s, i, m]
                out[s, i, j] = out[s, j, i] = 0.5 * (u + v)
    return out


def update(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, H: np.ndarray, R: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Kalman update of n predicted states with n measurements.

    Returns ``(x_upd, P_upd, nu, S)`` where ``nu = z − H x`` is the innovation and ``S``
    its covariance (both useful for gating and likelihoods)."""
    S = innovation_covariance(P, H, R)
    K = gain(P, H, S)
    nu = z - x @ H.T
    x_new = x + np.einsum("...ij,...j->...i", K, nu)
    return x_new, joseph_covariance(P, K, H, R), nu, S


def gaussian_log_likelihood(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """log N(nu; 0, S) for innovations nu (..., m) with covariances S (..., m, m)."""
    m = nu.shape[-1]
    L = np.linalg.cholesky(S)
    sol = np.linalg.solve(L, nu[..., None])[..., 0]
    d2 = np.einsum("...i,...i->...", sol, sol)
    logdet = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(-1)
    return -0.5 * (d2 + logdet + m * np.log(2.0 * np.pi))
