"""Moment matching of Gaussian mixtures, grouped (spec 02 §7 step 11 [LIT], thesis
4.66-4.68; spec 01 §5 IMM eq. 15-17 and 20-21).

One mechanism serves every merge in skyfuse: the Singer N-scan merge of ITS components,
the track output of a mixture, the IMM mixing step and the IMM output. Components carry a
group label; each group {ξ^n, x̂^n, P^n} becomes one Gaussian

    ξ^μ = Σ ξ^n,   x̂^μ = Σ ξ^n x̂^n / ξ^μ,   P^μ = Σ ξ^n [P^n + (x̂^n − x̂^μ)(x̂^n − x̂^μ)ᵀ] / ξ^μ.

Grouped sums are one ``np.add.reduceat`` over the components sorted by group: linear in
the number of components, no Python loop over them.
"""

from __future__ import annotations

import numpy as np


def segment_sum(values: np.ndarray, group: np.ndarray, ngroups: int) -> np.ndarray:
    """Σ of ``values`` (C, ...) over components with equal ``group``, shape (ngroups, ...).

    One ``np.add.reduceat`` over the components sorted by group (a stable sort, skipped
    when ``group`` is already non-decreasing): linear in C, no per-component Python, and
    the same summation order as a sequential sum."""
    out = np.zeros((ngroups, *values.shape[1:]))
    if len(values) == 0:
        return out
    group = np.asarray(group)
    if len(group) > 1 and (group[1:] < group[:-1]).any():
        order = np.argsort(group, kind="stable")
        group, values = group[order], values[order]
    starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
    out[group[starts]] = np.add.reduceat(values, starts, axis=0)
    return out


def moment_match(
    w: np.ndarray, x: np.ndarray, P: np.ndarray, group: np.ndarray, ngroups: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge components with equal ``group``: w (C,), x (C, d), P (C, d, d).

    Returns (W (G,), x (G, d), P (G, d, d)); groups of zero weight get an unweighted mean."""
    if len(w) == ngroups and np.array_equal(group, np.arange(ngroups)):
        # one component per group (GNN/IPDA tracks): nothing to merge
        return w.astype(np.float64, copy=True), x.copy(), 0.5 * (P + np.swapaxes(P, 1, 2))
    W = np.bincount(group, weights=w, minlength=ngroups)
    zero = W <= 0.0
    ww = w.copy()
    if zero.any():  # fall back to equal weights inside weightless groups
        ww[zero[group]] = 1.0
        Wn = np.bincount(group, weights=ww, minlength=ngroups)
    else:
        Wn = W
    xm = segment_sum(ww[:, None] * x, group, ngroups) / Wn[:, None]
    dx = x - xm[group]
    spread = P + dx[:, :, None] * dx[:, None, :]
    Pm = segment_sum(ww[:, None, None] * spread, group, ngroups) / Wn[:, None, None]
    Pm = 0.5 * (Pm + np.swapaxes(Pm, 1, 2))
    return W, xm, Pm


def moment_match_rows(
    w: np.ndarray, xs: np.ndarray, Ps: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Σ_r w[n, r] N(xs[n, r], Ps[n, r]) → (x (n, d), P (n, d, d)) for weights w (n, r)
    summing to 1 per row (IMM mixing and output): :func:`moment_match` with group = row."""
    n, r = w.shape
    d = xs.shape[-1]
    group = np.repeat(np.arange(n), r)
    _, x, P = moment_match(w.reshape(-1), xs.reshape(n * r, d), Ps.reshape(n * r, d, d), group, n)
    return x, P
