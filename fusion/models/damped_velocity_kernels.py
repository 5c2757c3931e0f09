"""Compiled (numba, ``cache=True``) terms and Kalman prediction of the damped-velocity
model (:mod:`fusion.models.damped_velocity`): per axis F_T = [[1, b], [0, e]] and
Q_T = q [[c², c b], [c b, b²]] with e = e^{−βT}, b = (1 − e)/β, c = (T − b)/β
(series for βT < 10⁻³, the CV values T and T²/2 at β = 0), the state interleaved
[x, vx, y, vy(, z, vz)] (m, m/s), T (n,) s per state:

    x⁻ = F x,   P⁻ = ½ (A + Aᵀ),   A = F P Fᵀ + Q,

written out per axis ((F M)_ij = M_ij + b M_(i+1)j for a position row i, e M_ij for a
velocity row), as :mod:`fusion.models.cv_kernels` does for CV.
"""

from __future__ import annotations

import numba
import numpy as np

_SERIES_BELOW = 1e-3


@numba.njit(cache=True, nogil=True)
def axis_terms(t: np.ndarray, beta: float):
    """(e, b, c) (n,) each for the intervals t (n,) s and the damping β (1/s)."""
    n = len(t)
    e, b, c = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        T = t[k]
        x = beta * T
        e[k] = np.exp(-x)
        if abs(x) < _SERIES_BELOW:  # b = T(1 − x/2 + x²/6), c = T²(1/2 − x/6 + x²/24)
            b[k] = T * (1.0 - x / 2.0 + x * x / 6.0)
            c[k] = T * T * (0.5 - x / 6.0 + x * x / 24.0)
        else:
            b[k] = -np.expm1(-x) / beta
            c[k] = (T - b[k]) / beta
    return e, b, c


@numba.njit(cache=True, nogil=True)
def predict(x, P, t, beta: float, q: float, q_vertical: float):
    """x (n, d), P (n, d, d), t (n,) s, β (1/s), q of the horizontal axes and q_vertical
    of the third axis (d = 6), m²/s⁴ → (x⁻, P⁻)."""
    n, d = x.shape
    e, b, c = axis_terms(t, beta)
    xp = np.empty((n, d))
    Pp = np.empty((n, d, d))
    FP = np.empty((d, d))
    for k in range(n):
        ek, bk, ck = e[k], b[k], c[k]
        for i in range(0, d, 2):
            xp[k, i] = x[k, i] + bk * x[k, i + 1]
            xp[k, i + 1] = ek * x[k, i + 1]
            for j in range(d):
                FP[i, j] = P[k, i, j] + bk * P[k, i + 1, j]
                FP[i + 1, j] = ek * P[k, i + 1, j]
        for i in range(d):
            for j in range(0, d, 2):
                Pp[k, i, j] = FP[i, j] + bk * FP[i, j + 1]
                Pp[k, i, j + 1] = ek * FP[i, j + 1]
        for a in range(d // 2):
            i, qa = 2 * a, (q_vertical if a == 2 else q)
            Pp[k, i, i] += qa * ck * ck
            Pp[k, i, i + 1] += qa * ck * bk
            Pp[k, i + 1, i] += qa * ck * bk
            Pp[k, i + 1, i + 1] += qa * bk * bk
        for i in range(d):
            for j in range(i + 1, d):
                h = 0.5 * (Pp[k, i, j] + Pp[k, j, i])
                Pp[k, i, j] = h
                Pp[k, j, i] = h
    return xp, Pp
