"""Fast paths of the IMM density and the sparse assignment (fixed per-step cost):
the stacked IMM mixing of every target mode ([Dikić] eq. 15-17), the one-child-per-track
Singer merge and track output (eq. 19-21), and the assignment's lean solver call.
References: the moment-matching sums written as Python loops, the IMM equations written
out for one track, and brute-force enumeration of assignments."""

import itertools

import numpy as np
import pytest
from skyfuse.fusion.association.assignment import assign_auction, assign_jv, assign_sparse
from skyfuse.fusion.filters.moment_matching import moment_match_rows_each
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.fusion.tracker.density.imm_mixture import IMMComponents, imm_density
from skyfuse.fusion.tracker.store import NewTracks, store_for


def _spd(rng, n, k):
    A = rng.normal(size=(n, k, k))
    return A @ A.transpose(0, 2, 1) + 0.5 * np.eye(k)


def _loop_mix(w, x, P):
    """Σ w_r N(x_r, P_r) moment-matched, one term at a time (equal weights if Σ w = 0)."""
    if w.sum() <= 0:
        w = np.ones_like(w)
    W = float(sum(w))
    m = sum(wi * xi for wi, xi in zip(w, x)) / W
    C = sum(wi * (Pi + np.outer(xi - m, xi - m)) for wi, xi, Pi in zip(w, x, P)) / W
    return m, C


def test_stacked_mixing_of_every_target_mode_against_a_loop():
    rng = np.random.default_rng(11)
    n, r, s, d = 6, 3, 2, 5
    w = rng.uniform(size=(n, r, s))
    w[2, :, 1] = 0.0  # a weightless column: equal weights
    x, P = rng.normal(size=(n, r, d)), _spd(rng, n * r, d).reshape(n, r, d, d)
    xm, Pm = moment_match_rows_each(w, x, P)
    assert xm.shape == (n, s, d) and Pm.shape == (n, s, d, d)
    for i in range(n):
        for j in range(s):
            m, C = _loop_mix(w[i, :, j], x[i], P[i])
            np.testing.assert_allclose(xm[i, j], m, rtol=1e-12, atol=1e-13)
            np.testing.assert_allclose(Pm[i, j], C, rtol=1e-12, atol=1e-13)


def _ct_density():
    d = imm_density(TrackerConfig(motion="imm-cv-ct"), "ct")
    rng = np.random.default_rng(5)
    x = np.column_stack(
        [rng.uniform(-5e3, 5e3, 4), rng.uniform(50, 200, 4), rng.uniform(-5e3, 5e3, 4),
         rng.uniform(-200, -50, 4)]
    )  # fmt: skip
    store_for(d).append(
        NewTracks(x, np.broadcast_to(np.diag([900.0, 100.0, 900.0, 100.0]), (4, 4, 4)).copy())
    )
    return d


def test_one_child_per_track_merge_against_the_equations():
    """Children of tracks 2, 0, 1 (unsorted, one each): the merge sorts them by track,
    keeps each mode's Gaussian (P symmetrised) and renormalises ξ μ_j."""
    d = _ct_density()
    rng = np.random.default_rng(6)
    r, dims = d.r, [m.dim for m in d.models]
    track = np.array([2, 0, 1])
    w = np.array([0.3, 0.9, 0.5])
    mu = rng.uniform(0.1, 1.0, size=(3, r))
    xs = [rng.normal(size=(3, k)) for k in dims]
    Ps = [rng.normal(size=(3, k, k)) for k in dims]  # not symmetric on purpose
    children = IMMComponents(track, w, np.zeros((3, 0), np.int64), mu, xs, Ps)
    out = d._merge(children)
    order = [1, 2, 0]
    np.testing.assert_array_equal(out.track, [0, 1, 2])
    np.testing.assert_allclose(out.w, w[order], rtol=0)
    ref_mu = (w[:, None] * mu) / (w[:, None] * mu).sum(axis=1, keepdims=True)
    np.testing.assert_allclose(out.mu, ref_mu[order], rtol=1e-15)
    for j in range(r):
        np.testing.assert_allclose(out.x[j], xs[j][order], rtol=0)
        np.testing.assert_allclose(out.P[j], 0.5 * (Ps[j] + Ps[j].swapaxes(1, 2))[order])


def test_track_output_with_one_component_per_track_against_the_equations():
    """eq. 20-21 per track: x = Σ_j μ_j x_j, P = Σ_j μ_j (P_j + spread) in the common
    layout, returned in the CV layout."""
    from skyfuse.fusion.models.conversions import to_common

    d = _ct_density()
    comp = d.comp
    cv = [0, 1, 3, 4]  # x, vx, y, vy in the common layout [x, vx, ax, y, vy, ay]
    x, P = d._track_estimates(comp, np.arange(len(comp)), len(comp))
    for t in range(len(comp)):
        common = [to_common(m, comp.x[j][t : t + 1], comp.P[j][t : t + 1])
                  for j, m in enumerate(d.models)]  # fmt: skip
        m, C = _loop_mix(comp.w[t] * comp.mu[t], [c[0][0] for c in common],
                         [c[1][0] for c in common])  # fmt: skip
        np.testing.assert_allclose(x[t], m[cv], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(P[t], C[np.ix_(cv, cv)], rtol=1e-10, atol=1e-8)


def _brute_force(n, k, pairs, miss):
    """Minimum total cost over every one-to-one assignment (None: no plot)."""
    cost = {(t, p): c for t, p, c in pairs}
    best = np.inf
    for choice in itertools.product(*[[None, *range(k)] for _ in range(n)]):
        plots = [p for p in choice if p is not None]
        if len(plots) != len(set(plots)) or any(
            p is not None and (t, p) not in cost for t, p in enumerate(choice)
        ):
            continue
        best = min(best, sum(miss[t] if p is None else cost[(t, p)] for t, p in enumerate(choice)))
    return best


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("solve", [assign_jv, assign_auction])
def test_sparse_assignment_against_brute_force(seed, solve):
    rng = np.random.default_rng(seed)
    n, k = 5, 4
    key = np.unique(rng.integers(0, n, 12) * k + rng.integers(0, k, 12))
    track, plot = key // k, key % k
    cost = rng.normal(size=len(key))
    miss = rng.uniform(-0.5, 0.5, n)
    rows = assign_sparse(track, plot, cost, miss, n, k, solve)
    chosen = rows[rows >= 0]
    assert len(set(plot[chosen].tolist())) == len(chosen)  # one track per plot
    assert (track[chosen] == np.flatnonzero(rows >= 0)).all()
    total = cost[chosen].sum() + miss[rows < 0].sum()
    pairs = list(zip(track.tolist(), plot.tolist(), cost.tolist()))
    assert total == pytest.approx(_brute_force(n, k, pairs, miss), abs=1e-6)


@pytest.mark.parametrize("vertical", [False, True])
def test_cv_layout_of_a_turn_state_against_a_numerical_jacobian(vertical):
    """x = (x, v cosψ, y, v sinψ(, z, vz)) and P = J P Jᵀ with J by central differences."""
    from skyfuse.fusion.models import CoordinatedTurn
    from skyfuse.fusion.models.conversions import to_cv_layout

    m = CoordinatedTurn(vertical=vertical)
    rng = np.random.default_rng(8)
    x = np.array([[1e3, -2e3, 0.7, 0.03, 150.0, 900.0, -4.0][: m.dim]])
    P = _spd(rng, 1, m.dim)

    def f(s):
        out = [s[0], s[4] * np.cos(s[2]), s[1], s[4] * np.sin(s[2])]
        return np.array(out + ([s[5], s[6]] if vertical else []))

    h = 1e-6
    J = np.column_stack([(f(x[0] + h * e) - f(x[0] - h * e)) / (2 * h) for e in np.eye(m.dim)])
    xo, Po = to_cv_layout(m, x, P)
    np.testing.assert_allclose(xo[0], f(x[0]), rtol=1e-14)
    np.testing.assert_allclose(Po[0], J @ P[0] @ J.T, rtol=1e-6, atol=1e-6)
