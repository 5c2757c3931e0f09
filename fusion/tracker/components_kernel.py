"""Compiled loops (numba, ``cache=True``) of the mixture components of a batch: the ITS
children ([thesis] 5.12-5.15), the Singer N-scan groups and merge ([thesis] §5.3),
pruning and the moment-matched track estimates (4.66-4.68) — the update of the
Gaussian-mixture density (:mod:`.density.gaussian_mixture`) in one call, and the grouping
and pruning the IMM density shares (:mod:`.components`).

The equations are those of :mod:`.its` and :mod:`.components`:

* children: the "no plot" child of component c has ξ^{c,0} = β₀ ξ^c, x̂^c, P^c and the
  history (0, h^c_0, …, h^c_{N−2}); the child of gated pair (c, i) has
  ξ^{c,i} = β_i ξ^c p^c_i / p^τ_i, the Kalman update with the pair's ν and S (Joseph form,
  :func:`fusion.filters.kalman.update_into`) and the history (uid_i, h^c_0, …); children
  of weight 0 are dropped (no Kalman update for them); the "no plot" children first, in
  component order, then the pairs' in pair order;
* Singer merge: the components of one track with equal histories are one group, groups in
  lexicographic order of (track, history) (a stable sort: a group's components in their
  order), moment-matched (:func:`fusion.filters.moment_matching.grouped_moments`); one
  component per track: taken in track order, P symmetrised;
* pruning: per track, ξ normalised, the components sorted by ξ (descending, stable), the
  first ``max_per_track`` kept if ξ ≥ ``threshold`` (the strongest always), ξ normalised
  again;
* the track estimate: the moment match of each track's kept components.

Every sum is taken in the order of the NumPy form these loops replaced (bincount,
reduceat-free grouped moments), so the results are the same to the last bit; the NumPy
form cost ≈ 300 array operations per batch (sorts, gathers, concatenations) on tens of
components, where each operation's fixed cost, not its arithmetic, was the time.
"""

from __future__ import annotations

import numba
import numpy as np
from skyfuse.fusion.filters.kalman import update_into, update_scratch
from skyfuse.fusion.filters.moment_matching import grouped_moments


@numba.njit(cache=True, nogil=True)
def _float_less(a, b):
    """a < b in NumPy's sort order (NaN last)."""
    return a < b or (b != b and a == a)


@numba.njit(cache=True, nogil=True)
def _row_less(keys, a, b):
    for j in range(keys.shape[1]):
        if keys[a, j] != keys[b, j]:
            return keys[a, j] < keys[b, j]
    return False


@numba.njit(cache=True, nogil=True)
def _track_weight_less(track, negw, a, b):
    if track[a] != track[b]:
        return track[a] < track[b]
    return _float_less(negw[a], negw[b])


@numba.njit(cache=True, nogil=True)
def _merge_pass(order, tmp, lo, mid, hi, keys, track, negw, by_rows):
    i, j, o = lo, mid, lo
    while i < mid and j < hi:
        if by_rows:
            right = _row_less(keys, order[j], order[i])
        else:
            right = _track_weight_less(track, negw, order[j], order[i])
        if right:  # only a strictly smaller right element goes first: stable
            tmp[o] = order[j]
            j += 1
        else:
            tmp[o] = order[i]
            i += 1
        o += 1
    while i < mid:
        tmp[o] = order[i]
        i += 1
        o += 1
    while j < hi:
        tmp[o] = order[j]
        j += 1
        o += 1


@numba.njit(cache=True, nogil=True)
def _stable_order(n, keys, track, negw, by_rows):
    """The stable sort of 0 … n−1 by the rows of ``keys`` (``by_rows``, lexicographic,
    as ``np.lexsort`` of the reversed columns) or by (track, −ξ) (as
    ``np.lexsort((negw, track))``): a bottom-up merge sort."""
    order = np.arange(n)
    tmp = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            _merge_pass(order, tmp, lo, mid, hi, keys, track, negw, by_rows)
        order, tmp = tmp, order
        width *= 2
    return order


@numba.njit(cache=True, nogil=True)
def history_groups(track, hist):
    """(group label per component, unique (track, history) rows in lexicographic order)
    of the Singer N-scan merge (labels as ``np.unique(keys, axis=0,
    return_inverse=True)``)."""
    C, N = hist.shape
    keys = np.empty((C, N + 1), np.int64)
    for c in range(C):
        keys[c, 0] = track[c]
        for a in range(N):
            keys[c, a + 1] = hist[c, a]
    if C < 2 or (track[1:] > track[:-1]).all():  # one component per track
        return np.arange(C), keys
    e = np.empty(0, np.int64)
    order = _stable_order(C, keys, e, np.empty(0), True)
    inv = np.empty(C, np.int64)
    uniq = np.empty((C, N + 1), np.int64)
    G = 0
    for s in range(C):
        c = order[s]
        if s == 0 or _row_less(keys, order[s - 1], c):
            for a in range(N + 1):
                uniq[G, a] = keys[c, a]
            G += 1
        inv[c] = G - 1
    return inv, uniq[:G]


@numba.njit(cache=True, nogil=True)
def _symmetrised(P):
    out = np.empty_like(P)
    for c in range(P.shape[0]):
        for a in range(P.shape[1]):
            for b in range(P.shape[2]):
                out[c, a, b] = 0.5 * (P[c, a, b] + P[c, b, a])
    return out


@numba.njit(cache=True, nogil=True)
def _moment_match(w, x, P, group, ngroups):
    """:func:`fusion.filters.moment_matching.moment_match` (its shortcut for one
    component per group in order, its stable sort, the grouped moments)."""
    C, d = x.shape
    identity = C == ngroups
    for c in range(C):
        if group[c] != c:
            identity = False
            break
    if identity:
        return w.copy(), x.copy(), _symmetrised(P)
    if C == 0:
        return np.zeros(ngroups), np.full((ngroups, d), np.nan), np.full((ngroups, d, d), np.nan)
    if not (group[1:] >= group[:-1]).all():
        order = np.argsort(group, kind="mergesort")
        w, x, P, group = w[order], x[order], P[order], group[order]
    n_starts = 1
    for c in range(1, C):
        if group[c] != group[c - 1]:
            n_starts += 1
    starts = np.empty(n_starts, np.int64)
    starts[0] = 0
    s = 1
    for c in range(1, C):
        if group[c] != group[c - 1]:
            starts[s] = c
            s += 1
    return grouped_moments(w, x, P, starts, group[starts], ngroups)


@numba.njit(cache=True, nogil=True)
def singer_merge(track, w, x, P, hist):
    """The Singer N-scan merge (module docstring): (track, ξ, x, P, history) per group."""
    C = len(w)
    if C == 0:
        return track, w, x, P, hist
    order = np.argsort(track, kind="mergesort")
    ts = track[order]
    if C < 2 or (ts[1:] > ts[:-1]).all():  # one component per track: in track order
        return ts, w[order], x[order], _symmetrised(P[order]), hist[order]
    inv, uniq = history_groups(track, hist)
    W, xm, Pm = _moment_match(w, x, P, inv, len(uniq))
    return uniq[:, 0].copy(), W, xm, Pm, uniq[:, 1:].copy()


@numba.njit(cache=True, nogil=True)
def _normalised(track, w, size):
    """ξ / Σ_track ξ (sums in component order, as ``np.bincount``; 0 sums divide by 1)."""
    tot = np.zeros(size)
    for c in range(len(w)):
        tot[track[c]] += w[c]
    out = np.empty(len(w))
    for c in range(len(w)):
        t = tot[track[c]]
        out[c] = w[c] / (t if t > 0 else 1.0)
    return out


@numba.njit(cache=True, nogil=True)
def prune_indices(track, w, threshold, max_per_track, ntracks):
    """(kept indices in order, their renormalised weights) of the pruning (module
    docstring)."""
    C = len(w)
    if C == 0:
        return np.zeros(0, np.int64), w.copy()
    if C < 2 or (track[1:] > track[:-1]).all():  # one component per track
        out = np.empty(C)
        for c in range(C):
            v = w[c] / (w[c] if w[c] > 0 else 1.0)
            out[c] = v / (v if v > 0 else 1.0)
        return np.arange(C), out
    size = max(ntracks, track.max() + 1)
    wn = _normalised(track, w, size)
    order = _stable_order(C, np.empty((0, 0), np.int64), track, -wn, False)
    keep = np.zeros(C, np.bool_)
    first = 0
    for s in range(C):
        c = order[s]
        if s > 0 and track[c] != track[order[s - 1]]:
            first = s
        rank = s - first
        keep[c] = rank < max_per_track and (wn[c] >= threshold or rank == 0)
    idx = np.flatnonzero(keep)
    return idx, _normalised(track[idx], wn[idx], size)


@numba.njit(cache=True, nogil=True)
def its_children(track, w, x, P, hist, loc, beta0, pairs, p_pair, p_track, beta, H, R, uid):
    """The children of weight > 0 (module docstring) of the predicted components (track,
    ξ, x, P, history; ``loc`` each one's index into the association arrays) given β₀ per
    track and β per table row; ``pairs``: (component, plot, table row, ν, S) of the gated
    pairs, p_pair p^c_i, p_track p^τ_i per row; H (k, d); R (m, k, k); uid (m,) the plots'
    history ids. Returns (track, ξ, x, P, history)."""
    state, plot, row, nu, S = pairs
    C, d = x.shape
    N, k = hist.shape[1], nu.shape[1]
    w0 = np.empty(C)
    wi = np.empty(len(state))
    n = 0
    for c in range(C):
        w0[c] = w[c] * beta0[loc[c]]
        n += w0[c] > 0.0
    for q in range(len(state)):
        wi[q] = w[state[q]] * beta[row[q]] * p_pair[q] / p_track[row[q]]
        n += wi[q] > 0.0
    ct, cw = np.empty(n, np.int64), np.empty(n)
    cx, cP, ch = np.empty((n, d)), np.empty((n, d, d)), np.empty((n, N), np.int64)
    o = 0
    for c in range(C):
        if w0[c] > 0.0:
            ct[o], cw[o] = track[c], w0[c]
            for a in range(d):
                cx[o, a] = x[c, a]
                for b in range(d):
                    cP[o, a, b] = P[c, a, b]
            _shifted(hist, c, 0, ch, o)
            o += 1
    scratch = update_scratch(d, k)
    for q in range(len(state)):
        if wi[q] > 0.0:
            c, j = state[q], plot[q]
            ct[o], cw[o] = track[c], wi[q]
            update_into(x[c], P[c], H, S[q], nu[q], R[j], cx[o], cP[o], scratch)
            _shifted(hist, c, uid[j], ch, o)
            o += 1
    return ct, cw, cx, cP, ch


@numba.njit(cache=True, nogil=True)
def _shifted(hist, c, first, out, o):
    """out[o] = (first, hist[c, 0], …, hist[c, N−2]) (N = 0: nothing)."""
    N = hist.shape[1]
    if N:
        out[o, 0] = first
        for a in range(1, N):
            out[o, a] = hist[c, a - 1]


@numba.njit(cache=True, nogil=True)
def merge_prune_estimate(children, rows, threshold, max_per_track, ntracks):
    """The Singer merge and the pruning of the ``children`` (track, ξ, x, P, history) of
    the tracks ``rows`` (sorted) and the tracks' moment-matched estimates: (kept
    components (track, ξ, x, P, history), number merged, x (s, d), P (s, d, d))."""
    track, w, x, P, hist = children
    mt, mw, mx, mP, mh = singer_merge(track, w, x, P, hist)
    keep, kw = prune_indices(mt, mw, threshold, max_per_track, ntracks)
    kt, kx, kP, kh = mt[keep], mx[keep], mP[keep], mh[keep]
    loc = np.searchsorted(rows, kt)
    _, tx, tP = _moment_match(kw, kx, kP, loc, len(rows))
    return (kt, kw, kx, kP, kh), len(mw), tx, tP


@numba.njit(cache=True, nogil=True)
def its_update(pred, loc, beta0, pairs, p_pair, p_track, beta, H, R, uid, rows, prune):
    """:func:`its_children` then :func:`merge_prune_estimate` (``prune``: threshold,
    max_per_track, ntracks): one batch's update of the Gaussian mixtures."""
    track, w, x, P, hist = pred
    children = its_children(track, w, x, P, hist, loc, beta0, pairs, p_pair, p_track, beta,
                            H, R, uid)  # fmt: skip
    return merge_prune_estimate(children, rows, prune[0], prune[1], prune[2])
