"""Compiled loops of the gating (:mod:`fusion.association.gating`; [MZD] §5, eq.
16-20; [thesis] (5.7)), numba with ``cache=True``.

* :func:`box_pairs`: the pre-gate's windows. The plots are sorted by their first
  coordinate; state i's window is the sorted positions ``lo[i]:hi[i]`` (from
  ``searchsorted(x_i ± r_i)``); a plot j of the window is kept when
  |points[j, a] − centres[i, a]| ≤ r_i in every other coordinate a as well.
* :func:`exact_gate`: for the pre-gated pairs (c, j), S = HPHᵀ_c + R_j, ν = z_j − ŷ_c,
  d² = νᵀ S⁻¹ ν and ln det S; the pair is kept when d² < g. For k = 2 the closed forms
  det S = s₀₀ s₁₁ − s₀₁², d² = (s₁₁ ν₀² − 2 s₀₁ ν₀ ν₁ + s₀₀ ν₁²) / det S (no LAPACK
  call: they agree with the factorisation to rounding for the well-conditioned
  S = H P Hᵀ + R of a tracker), otherwise the Cholesky factor of
  :mod:`fusion.filters.cholesky_kernels` (d² = |L⁻¹ν|², ln det S = 2 Σ ln L_aa); an S that
  is not positive definite is outside every gate.

* :func:`windows`: the sort, the binary searches and :func:`box_pairs`;
* :func:`gate_pairs`: the windows' radii, :func:`windows` and :func:`exact_gate` in one
  call.

The NumPy form of both costs a dozen array operations (a gather, a temporary and a
filter per output) on the tens of pairs of one sector batch, where each operation's
fixed cost exceeds its arithmetic; one loop over the pairs does the same work once.
The output order is the NumPy form's: by state, then by the plots' sorted position.
Units are those of the inputs (m, m²).
"""

from __future__ import annotations

import numba
import numpy as np
from skyfuse.fusion.filters.cholesky_kernels import cholesky_into


@numba.njit(cache=True, nogil=True)
def box_pairs(order, lo, hi, centres, radii, points):
    """(i, j) of the windows ``lo[i]:hi[i]`` of the sorted plots ``order`` that pass the
    box test in coordinates 1…k−1 (coordinate 0 is the window itself)."""
    n, k = centres.shape
    total = 0
    for i in range(n):
        total += max(hi[i] - lo[i], 0)
    out_i = np.empty(total, np.int64)
    out_j = np.empty(total, np.int64)
    p = 0
    for i in range(n):
        r = radii[i]
        for t in range(lo[i], hi[i]):
            j = order[t]
            inside = True
            for a in range(1, k):
                if abs(points[j, a] - centres[i, a]) > r:
                    inside = False
                    break
            if inside:
                out_i[p] = i
                out_j[p] = j
                p += 1
    return out_i[:p], out_j[:p]


@numba.njit(cache=True, nogil=True)
def windows(centres, radii, points):
    """(i, j) with |points[j] − centres[i]| ≤ radii[i] in every coordinate: the points
    sorted by their first coordinate (stable), each centre's window by binary search,
    then :func:`box_pairs`."""
    order = np.argsort(points[:, 0], kind="mergesort")
    xs = points[order, 0]
    lo = np.searchsorted(xs, centres[:, 0] - radii)
    hi = np.searchsorted(xs, centres[:, 0] + radii, side="right")
    return box_pairs(order, lo, hi, centres, radii, points)


@numba.njit(cache=True, nogil=True)
def statistics_2x2(S, nu):
    """d², ln det S of one 2 × 2 pair by the closed forms (d² = ∞: not positive definite)."""
    a, b, c = S[0, 0], S[0, 1], S[1, 1]
    det = a * c - b * b
    x, y = nu[0], nu[1]
    if not (a > 0.0 and det > 0.0):
        return np.inf, np.log(det) if det > 0.0 else np.nan
    return (c * x * x - 2.0 * b * x * y + a * y * y) / det, np.log(det)


@numba.njit(cache=True, nogil=True)
def statistics_cholesky(S, nu, L, w):
    """d², ln det S of one k × k pair from its Cholesky factor (∞, NaN: not PD)."""
    k = S.shape[0]
    if not cholesky_into(S, L):
        return np.inf, np.nan
    d2 = 0.0
    logdet = 0.0
    for a in range(k):
        t = nu[a]
        for m in range(a):
            t -= L[a, m] * w[m]
        w[a] = t / L[a, a]
        d2 += w[a] * w[a]
        logdet += np.log(L[a, a])
    return d2, 2.0 * logdet


@numba.njit(cache=True, nogil=True)
def exact_gate(ci, pj, y, HPH, z, R, use_R, g):
    """Pairs of (ci, pj) with d² < g: (keep indices into ci, ν, S, d², ln det S)."""
    n, k = len(ci), y.shape[1]
    keep = np.empty(n, np.int64)
    nu_out = np.empty((n, k))
    S_out = np.empty((n, k, k))
    d2_out = np.empty(n)
    ld_out = np.empty(n)
    S = np.empty((k, k))
    nu = np.empty(k)
    L = np.zeros((k, k))
    w = np.empty(k)
    p = 0
    for q in range(n):
        c, j = ci[q], pj[q]
        for a in range(k):
            nu[a] = z[j, a] - y[c, a]
            for b in range(k):
                S[a, b] = HPH[c, a, b] + R[j, a, b] if use_R else HPH[c, a, b]
        if k == 2:
            d2, ld = statistics_2x2(S, nu)
        else:
            d2, ld = statistics_cholesky(S, nu, L, w)
        if d2 < g:
            keep[p] = q
            nu_out[p] = nu
            S_out[p] = S
            d2_out[p] = d2
            ld_out[p] = ld
            p += 1
    return keep[:p], nu_out[:p], S_out[:p], d2_out[:p], ld_out[:p]


@numba.njit(cache=True, nogil=True)
def gate_pairs(y, HPH, z, R, use_R, g):
    """The whole gate of :func:`fusion.association.gating.gate` in one call: the radius
    r_c = √(g (tr HPHᵀ_c + max_j tr R_j)) of every state, the plots sorted by their first
    coordinate (stable), the windows, :func:`box_pairs` and :func:`exact_gate`. Returns
    (state, plot, ν, S, d², ln det S, pairs that passed the pre-gate)."""
    n, k = y.shape
    trR = 0.0
    if use_R:
        for j in range(len(R)):
            t = 0.0
            for a in range(k):
                t += R[j, a, a]
            trR = max(trR, t) if j else t
    radius = np.empty(n)
    for c in range(n):
        t = 0.0
        for a in range(k):
            t += HPH[c, a, a]
        radius[c] = np.sqrt(g * (t + trR))
    ci, pj = windows(y, radius, z)
    keep, nu, S, d2, logdet = exact_gate(ci, pj, y, HPH, z, R, use_R, g)
    return ci[keep], pj[keep], nu, S, d2, logdet, len(ci)
