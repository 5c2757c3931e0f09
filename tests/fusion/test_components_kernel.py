"""The compiled update of the Gaussian mixtures (fusion/tracker/components_kernel.py)
against references written out here: the ITS children of 5.12-5.15 with an explicit
inverse, the Singer groups as a dictionary of (track, history), the moment match and
the pruning as loops, np.unique for the groups' order."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker import components_kernel as kernel


def _random_mixture(rng, ntracks, depth, d=4):
    per = rng.integers(1, 5, ntracks)
    track = np.repeat(np.arange(ntracks), per)
    C = len(track)
    w = rng.uniform(0.05, 1.0, C)
    x = rng.normal(0, 100, (C, d))
    A = rng.normal(size=(C, d, d))
    P = A @ A.transpose(0, 2, 1) + 10 * np.eye(d)
    hist = rng.integers(0, 3, (C, depth))
    return track, w, x, P, hist


def _reference(track, w, x, P, hist, loc, beta0, pairs, p_pair, p_track, beta, H, R, uid,
               rows, thr, cap):  # fmt: skip
    """Children, groups, merge, pruning and track moments, one loop each."""
    state, plot, row, nu, S = pairs
    kids = [(track[c], w[c] * beta0[loc[c]], x[c], P[c], (0, *hist[c][:-1]) if hist.shape[1]
             else ()) for c in range(len(w))]  # fmt: skip
    I = np.eye(x.shape[1])
    for q in range(len(state)):
        c, i = state[q], plot[q]
        wi = w[c] * beta[row[q]] * p_pair[q] / p_track[row[q]]
        K = P[c] @ H.T @ np.linalg.inv(S[q])
        A = I - K @ H
        Pn = A @ P[c] @ A.T + K @ R[i] @ K.T
        h = (uid[i], *hist[c][:-1]) if hist.shape[1] else ()
        kids.append((track[c], wi, x[c] + K @ nu[q], Pn, h))
    kids = [k for k in kids if k[1] > 0]
    groups: dict = {}
    for t, wk, xk, Pk, h in kids:
        groups.setdefault((t, *h), []).append((wk, xk, Pk))
    merged = []
    for key in sorted(groups):
        ws = np.array([g[0] for g in groups[key]])
        xm = sum(g[0] * g[1] for g in groups[key]) / ws.sum()
        Pm = sum(g[0] * (g[2] + np.outer(g[1] - xm, g[1] - xm)) for g in groups[key]) / ws.sum()
        merged.append((key, ws.sum(), xm, 0.5 * (Pm + Pm.T)))
    kept = []
    for t in sorted({m[0][0] for m in merged}):
        mine = [m for m in merged if m[0][0] == t]
        tot = sum(m[1] for m in mine)
        mine = sorted(mine, key=lambda m: -m[1] / tot)
        keep = [m for r, m in enumerate(mine) if r < cap and (m[1] / tot >= thr or r == 0)]
        tk = sum(m[1] for m in keep)
        kept += [(m[0], m[1] / tk, m[2], m[3]) for m in keep]
    kept.sort(key=lambda m: m[0])
    est = {}
    for r in rows:
        mine = [m for m in kept if m[0][0] == r]
        W = sum(m[1] for m in mine)
        xm = sum(m[1] * m[2] for m in mine) / W
        est[r] = (xm, sum(m[1] * (m[3] + np.outer(m[2] - xm, m[2] - xm)) for m in mine) / W)
    return len(merged), kept, est


@pytest.mark.parametrize("depth, seed", [(0, 1), (1, 2), (2, 3), (3, 4)])
def test_its_update_against_the_equations(depth, seed):
    rng = np.random.default_rng(seed)
    ntracks, m, d = 5, 6, 4
    track, w, x, P, hist = _random_mixture(rng, ntracks, depth, d)
    rows = np.arange(ntracks)
    loc = track.copy()
    H = np.zeros((2, d))
    H[0, 0] = H[1, 2] = 1.0
    R = np.stack([np.diag(rng.uniform(50, 200, 2)) for _ in range(m)])
    state = np.sort(rng.choice(len(w), 9))
    plot = rng.integers(0, m, 9)
    S = np.stack([H @ P[c] @ H.T + R[i] for c, i in zip(state, plot)])
    nu = rng.normal(0, 20, (9, 2))
    # table rows: one per (track, plot) of the pairs
    keys = track[state] * m + plot
    uniq, row = np.unique(keys, return_inverse=True)
    p_pair = rng.uniform(0.0, 2e-4, 9)
    p_pair[0] = 0.0  # a child of weight 0 is dropped
    p_track = np.bincount(row, weights=w[state] * p_pair) + 1e-6
    beta = rng.uniform(0.0, 0.3, len(uniq))
    beta0 = rng.uniform(0.1, 0.9, ntracks)
    beta0[1] = 0.0  # a track whose "no plot" children all weigh 0
    uid = np.arange(1, m + 1, dtype=np.int64) + 10
    pairs = (state, plot, row.astype(np.int64), nu, S)
    thr, cap = 0.05, 3
    kept, merged, tx, tP = kernel.its_update(
        (track, w, x, P, hist), loc, beta0, pairs, p_pair, p_track, beta, H, R, uid, rows,
        (thr, cap, ntracks),
    )  # fmt: skip
    n_ref, kept_ref, est = _reference(track, w, x, P, hist, loc, beta0, pairs, p_pair,
                                      p_track, beta, H, R, uid, rows, thr, cap)  # fmt: skip
    assert merged == n_ref
    kt, kw, kx, kP, kh = kept
    assert [(t, *h) for t, h in zip(kt, kh.tolist())] == [k[0] for k in kept_ref]
    np.testing.assert_allclose(kw, [k[1] for k in kept_ref], rtol=1e-12)
    np.testing.assert_allclose(kx, np.array([k[2] for k in kept_ref]), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(kP, np.array([k[3] for k in kept_ref]), rtol=1e-9, atol=1e-9)
    for r in rows:
        np.testing.assert_allclose(tx[r], est[r][0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(tP[r], est[r][1], rtol=1e-9, atol=1e-9)


def test_history_groups_against_np_unique():
    rng = np.random.default_rng(7)
    track = np.sort(rng.integers(0, 6, 80))
    hist = rng.integers(0, 3, (80, 2))
    inv, uniq = kernel.history_groups(track, hist)
    keys, ref_inv = np.unique(np.column_stack([track, hist]), axis=0, return_inverse=True)
    np.testing.assert_array_equal(uniq, keys)
    np.testing.assert_array_equal(inv, ref_inv.reshape(-1))


def test_prune_indices_against_a_loop_with_ties_and_zeros():
    rng = np.random.default_rng(8)
    track = np.sort(rng.integers(0, 8, 120))
    w = rng.choice([0.0, 0.001, 0.01, 0.2, 0.2, 0.5], 120)  # ties and zero weights
    thr, cap = 0.02, 4
    keep, wk = kernel.prune_indices(track, w, thr, cap, 8)
    ref = []
    for t in np.unique(track):
        idx = np.flatnonzero(track == t)
        tot = w[idx].sum()
        wn = w[idx] / (tot if tot > 0 else 1.0)
        order = sorted(range(len(idx)), key=lambda i: -wn[i])  # stable: ties in order
        ref += [idx[i] for r, i in enumerate(order) if r < cap and (wn[i] >= thr or r == 0)]
    np.testing.assert_array_equal(keep, np.sort(ref))
    for t in np.unique(track[keep]):
        assert wk[track[keep] == t].sum() == pytest.approx(1.0) or (w[track == t] == 0).all()
