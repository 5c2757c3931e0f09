"""Compiled loops of the common-target pairing (:mod:`.common_target`, eq. 2-3), numba
with ``cache=True``.

* :func:`partner_rows`: the rule of :meth:`.common_target.PairBuffer._partners`. Each new
  plot i takes, among the stored plots of its track (the window ``lo[i]:hi[i]`` of the
  store sorted by track), one of another radar with |t_i − t_j| ≤ max_dt nearest in time
  (ties: the lowest stored row); then each stored row keeps the new plot nearest in time
  (ties: the lowest new row). Pairs in the order of their stored row.
* :func:`pair_residuals`: y = z_A − z_B − v_A Δt + H_A β̂_A − H_B β̂_B and
  W = R_A + R_B + Δt² P_vv + q |Δt|³/3 I per pair (eq. 2-3), Δt = t_A − t_B in s.

In NumPy both took ≈ 40 array operations (candidate expansion, two lexsorts, gathers of
nine columns) on the few tens of plots of a sector batch: ≈ 90 µs against ≈ 10 µs here.
Times in ns, positions m, velocities m/s.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def partner_rows(order, lo, hi, new_radar, new_time, s_radar, s_time, max_dt):
    """(ia, ib): rows of the new plots and of their stored partners (see the module)."""
    n, m = len(new_time), len(s_time)
    best_b = np.full(n, -1, np.int64)
    best_c = np.zeros(n, np.int64)
    for i in range(n):
        for t in range(lo[i], hi[i]):
            j = order[t]
            if s_radar[j] == new_radar[i]:
                continue
            c = abs(new_time[i] - s_time[j])
            if c > max_dt:
                continue
            if best_b[i] < 0 or c < best_c[i] or (c == best_c[i] and j < best_b[i]):
                best_b[i], best_c[i] = j, c
    win = np.full(m, -1, np.int64)
    win_c = np.zeros(m, np.int64)
    count = 0
    for i in range(n):
        j = best_b[i]
        if j < 0:
            continue
        if win[j] < 0:
            count += 1
            win[j], win_c[j] = i, best_c[i]
        elif best_c[i] < win_c[j]:  # (equal |dt|: the lower new row i, seen first, stays)
            win[j], win_c[j] = i, best_c[i]
    ia = np.empty(count, np.int64)
    ib = np.empty(count, np.int64)
    k = 0
    for j in range(m):
        if win[j] >= 0:
            ia[k], ib[k] = win[j], j
            k += 1
    return ia, ib


@numba.njit(cache=True, nogil=True)
def pair_residuals(tA, tB, zA, zB, vA, HA, HB, bA, bB, RA, RB, Pvv, q):
    """y (k, 2), W (k, 2, 2) of the pairs (eq. 2-3)."""
    k = len(tA)
    y = np.empty((k, 2))
    W = np.empty((k, 2, 2))
    for p in range(k):
        dt = (tA[p] - tB[p]) * 1e-9
        for a in range(2):
            ha = 0.0
            hb = 0.0
            for c in range(4):
                ha += HA[p, a, c] * bA[p, c]
                hb += HB[p, a, c] * bB[p, c]
            y[p, a] = zA[p, a] - zB[p, a] - vA[p, a] * dt + ha - hb
            for b in range(2):
                W[p, a, b] = RA[p, a, b] + RB[p, a, b] + dt**2 * Pvv[p, a, b]
        motion = q * abs(dt) ** 3 / 3.0
        W[p, 0, 0] += motion
        W[p, 1, 1] += motion
    return y, W
