"""Compiled (numba, ``cache=True``) Kalman prediction of n states of the nearly-constant-
velocity model (:mod:`fusion.models.cv`; [MZD] eq. 5-7, [thesis] (5.4)):

    x⁻ = F x,   P⁻ = ½ (A + Aᵀ),   A = F P Fᵀ + Q,

with F block-diagonal per axis a, F_a = [[1, T], [0, 1]], and Q_a = q_a [[T⁴/4, T³/2],
[T³/2, T²]] (q_a the acceleration variance of axis a, m²/s⁴: q horizontally, q_vertical
for z), the state interleaved [x, vx, y, vy(, z, vz)] (m, m/s), T (n,) s per state.
Because F is 1 on the diagonal and T in the (position, velocity) entry of each axis,
(F M)_ij = M_ij + T M_(i+1)j for a position row i and M_ij for a velocity row: the
products are written out with those terms. In NumPy the same prediction built F
(n, d, d) and Q (n, d, d) and multiplied them (10–15 array operations; at a few dozen
states their per-call cost, not the arithmetic, was the time: 90–110 µs against 5–8 µs
here). The results agree with the matrix products to rounding.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def predict(x: np.ndarray, P: np.ndarray, t: np.ndarray, q: float, q_vertical: float):
    """x (n, d), P (n, d, d), t (n,) s, q of the horizontal axes and q_vertical of the
    third axis (d = 6), m²/s⁴ → (x⁻, P⁻)."""
    n, d = x.shape
    xp = np.empty((n, d))
    Pp = np.empty((n, d, d))
    FP = np.empty((d, d))
    for k in range(n):
        tk = t[k]
        for i in range(0, d, 2):
            xp[k, i] = x[k, i] + tk * x[k, i + 1]
            xp[k, i + 1] = x[k, i + 1]
            for j in range(d):
                FP[i, j] = P[k, i, j] + tk * P[k, i + 1, j]
                FP[i + 1, j] = P[k, i + 1, j]
        for i in range(d):
            for j in range(0, d, 2):
                Pp[k, i, j] = FP[i, j] + tk * FP[i, j + 1]
                Pp[k, i, j + 1] = FP[i, j + 1]
        for a in range(d // 2):
            i, qa = 2 * a, (q_vertical if a == 2 else q)
            Pp[k, i, i] += qa * tk**4 / 4
            Pp[k, i, i + 1] += qa * tk**3 / 2
            Pp[k, i + 1, i] += qa * tk**3 / 2
            Pp[k, i + 1, i + 1] += qa * tk**2
        for i in range(d):
            for j in range(i + 1, d):
                h = 0.5 * (Pp[k, i, j] + Pp[k, j, i])
                Pp[k, i, j] = h
                Pp[k, j, i] = h
    return xp, Pp
