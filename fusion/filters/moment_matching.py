"""Moment matching of Gaussian mixtures, grouped ([LIT]; [thesis]
(4.66-4.68); IMM mixing and output, [Dikić] eq. 15-17 and 20-21).

One mechanism serves every merge in skyfuse: the Singer N-scan merge of ITS components,
the track output of a mixture, the IMM mixing step and the IMM output. Components carry a
group label; each group {ξ^n, x̂^n, P^n} becomes one Gaussian

    ξ^μ = Σ ξ^n,   x̂^μ = Σ ξ^n x̂^n / ξ^μ,   P^μ = Σ ξ^n [P^n + (x̂^n − x̂^μ)(x̂^n − x̂^μ)ᵀ] / ξ^μ.

The grouped merge runs over the components sorted by group in one compiled loop
(numba: no (C, d, d) temporaries), summing each group's terms sequentially in the
components' order; the other grouped sums are ``np.add.reduceat`` calls. Both are linear
in the number of components, with no Python loop over them; the two agree to rounding
(``reduceat`` associates long sums differently).
"""

from __future__ import annotations

import numba
import numpy as np


def _segment_starts(group: np.ndarray) -> np.ndarray:
    """Indices where a run of equal labels starts in a non-decreasing ``group`` (C ≥ 1)."""
    change = np.empty(len(group), bool)
    change[0] = True
    np.not_equal(group[1:], group[:-1], out=change[1:])
    return np.flatnonzero(change)


def _is_sorted(group: np.ndarray) -> bool:
    return len(group) < 2 or not (group[1:] < group[:-1]).any()


def segment_sum(values: np.ndarray, group: np.ndarray, ngroups: int) -> np.ndarray:
    """Σ of ``values`` (C, ...) over components with equal ``group``, shape (ngroups, ...).

    One ``np.add.reduceat`` over the components sorted by group (a stable sort, skipped
    when ``group`` is already non-decreasing): linear in C, no per-component Python, and
    the same summation order as a sequential sum."""
    out = np.zeros((ngroups, *values.shape[1:]))
    if len(values) == 0:
        return out
    group = np.asarray(group)
    if not _is_sorted(group):
        order = np.argsort(group, kind="stable")
        group, values = group[order], values[order]
    starts = _segment_starts(group)
    out[group[starts]] = np.add.reduceat(values, starts, axis=0)
    return out


def moment_match(
    w: np.ndarray, x: np.ndarray, P: np.ndarray, group: np.ndarray, ngroups: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge components with equal ``group``: w (C,), x (C, d), P (C, d, d).

    Returns (W (G,), x (G, d), P (G, d, d)); groups of zero weight get an unweighted mean.
    The components are sorted by group once (stable, skipped when already sorted); the
    moments of each run are then summed in the components' order within the group
    (:func:`grouped_moments`)."""
    group = np.asarray(group)
    if len(w) == ngroups and np.array_equal(group, np.arange(ngroups)):
        # one component per group (GNN/IPDA tracks): nothing to merge
        return w.astype(np.float64, copy=True), x.copy(), 0.5 * (P + P.swapaxes(1, 2))
    if len(w) == 0:
        d = x.shape[1]  # groups without components: no mean (NaN), as 0 / 0
        return np.zeros(ngroups), np.full((ngroups, d), np.nan), np.full((ngroups, d, d), np.nan)
    if not _is_sorted(group):
        order = np.argsort(group, kind="stable")
        w, x, P, group = w[order], x[order], P[order], group[order]
    starts = _segment_starts(group)
    return grouped_moments(
        np.ascontiguousarray(w, dtype=np.float64),
        np.ascontiguousarray(x, dtype=np.float64),
        np.ascontiguousarray(P, dtype=np.float64),
        starts,
        group[starts].astype(np.int64),
        ngroups,
    )


@numba.njit(cache=True, nogil=True)
def grouped_moments(w, x, P, starts, gid, ngroups):
    """W, x̂^μ, P^μ of the runs of sorted components at ``starts`` (labels ``gid``);
    groups without components: W 0 and NaN moments; a run of zero total weight: equal
    weights (see :func:`moment_match`)."""
    C, d = x.shape
    W = np.zeros(ngroups)
    xm = np.full((ngroups, d), np.nan)
    Pm = np.full((ngroups, d, d), np.nan)
    dx = np.empty(d)
    mean = np.empty(d)
    acc = np.empty((d, d))
    for s in range(len(starts)):
        lo = starts[s]
        hi = starts[s + 1] if s + 1 < len(starts) else C
        g = gid[s]
        tot = 0.0
        for c in range(lo, hi):
            tot += w[c]
        W[g] = tot
        equal = not tot > 0.0
        wn = 0.0
        for c in range(lo, hi):
            wn += 1.0 if equal else w[c]
        mean[:] = 0.0
        for c in range(lo, hi):
            wc = 1.0 if equal else w[c]
            for a in range(d):
                mean[a] += wc * x[c, a]
        for a in range(d):
            mean[a] /= wn
        acc[:, :] = 0.0
        for c in range(lo, hi):
            wc = 1.0 if equal else w[c]
            for a in range(d):
                dx[a] = x[c, a] - mean[a]
            for a in range(d):
                for b in range(d):
                    acc[a, b] += wc * (P[c, a, b] + dx[a] * dx[b])
        for a in range(d):
            xm[g, a] = mean[a]
            for b in range(d):
                Pm[g, a, b] = acc[a, b] / wn
        for a in range(d):
            for b in range(d):
                acc[a, b] = 0.5 * (Pm[g, a, b] + Pm[g, b, a])
        for a in range(d):
            for b in range(d):
                Pm[g, a, b] = acc[a, b]
    return W, xm, Pm


def moment_match_rows(
    w: np.ndarray, xs: np.ndarray, Ps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Σ_r w[n, r] N(xs[n, r], Ps[n, r]) → (x (n, d), P (n, d, d)) for weights w (n, r)
    summing to 1 per row (IMM mixing and output): :func:`moment_match` with group = row,
    written as sums over the mode axis (no grouping needed: every row is a group);
    :func:`moment_match_rows_each` with one weighting."""
    xm, Pm = moment_match_rows_each(w[:, :, None], xs, Ps)
    return xm[:, 0], Pm[:, 0]


def moment_match_rows_each(
    w: np.ndarray, xs: np.ndarray, Ps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`moment_match_rows` for s weightings at once: w (n, r, s) with columns
    summing to 1 → x (n, s, d), P (n, s, d, d), column j the mixture Σ_r w[n, r, j]
    N(xs[n, r], Ps[n, r]) (the IMM mixing of eq. 15-17 for every target mode j in one
    stacked array; the same sums over the mode axis as s calls of moment_match_rows)."""
    f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    return _rows_each(f64(w), f64(xs), f64(Ps))


@numba.njit(cache=True, nogil=True)
def _rows_each(w, xs, Ps):
    """The loops of :func:`moment_match_rows_each`: per row n and weighting j, W = Σ_r w,
    x̂ = Σ_r w x_r / W, P̂ = Σ_r w (P_r + (x_r − x̂)(x_r − x̂)ᵀ) / W, symmetrised; a
    weighting of total weight ≤ 0 takes equal weights."""
    n, r, s = w.shape
    d = xs.shape[2]
    xm = np.zeros((n, s, d))
    Pm = np.zeros((n, s, d, d))
    dx = np.empty(d)
    for k in range(n):
        for j in range(s):
            W = 0.0
            for m in range(r):
                W += w[k, m, j]
            equal = W <= 0.0
            if equal:
                W = float(r)
            for m in range(r):
                wm = 1.0 if equal else w[k, m, j]
                for a in range(d):
                    xm[k, j, a] += wm * xs[k, m, a]
            for a in range(d):
                xm[k, j, a] /= W
            for m in range(r):
                wm = 1.0 if equal else w[k, m, j]
                for a in range(d):
                    dx[a] = xs[k, m, a] - xm[k, j, a]
                for a in range(d):
                    for b in range(d):
                        Pm[k, j, a, b] += wm * (Ps[k, m, a, b] + dx[a] * dx[b])
            for a in range(d):
                for b in range(a, d):
                    h = 0.5 * (Pm[k, j, a, b] / W + Pm[k, j, b, a] / W)
                    Pm[k, j, a, b] = h
                    Pm[k, j, b, a] = h
    return xm, Pm
