"""Gating and assignment against brute force; auction == Jonker-Volgenant (hypothesis).
(The GNN life cycle on scripted scenes: tests/fusion/test_tracker_m_of_n.py.)"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from skyfuse.fusion.association import (
    assign_auction,
    assign_jv,
    gate,
    gate_threshold,
    split_clusters,
    total_cost,
)
from skyfuse.fusion.association.assignment import EPS_FINAL_RELATIVE


def test_gate_threshold_is_the_chi_square_quantile():
    assert gate_threshold(0.9997, 2) == pytest.approx(-2 * np.log(1 - 0.9997), rel=1e-9)
    assert gate_threshold(0.9997, 2) == pytest.approx(16.2235, abs=1e-4)
    assert gate_threshold(0.99, 3) == pytest.approx(11.3449, abs=1e-4)
    with pytest.raises(ValueError, match=r"p_gate = 1\.5"):
        gate_threshold(1.5, 2)


def test_gate_threshold_and_probability_equal_scipy_stats_chi2():
    """The incomplete-gamma forms are scipy.stats.chi2's ppf and cdf, to the bit, for
    every dimension the trackers use (plots 1-3, states 2-9) and the probabilities they
    are configured with."""
    from scipy.stats import chi2
    from skyfuse.fusion.association.gating import gate_probability

    for k in range(1, 10):
        for p in (1e-6, 0.5, 0.9, 0.95, 0.99, 0.999, 0.9997, 0.999999):
            g = gate_threshold(p, k)
            assert g == float(chi2.ppf(p, k))
            assert gate_probability(g, k) == float(chi2.cdf(g, k))
            assert gate_probability(g, k) == pytest.approx(p, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 12), st.integers(0, 15), st.sampled_from([2, 3]))
def test_gate_equals_brute_force_mahalanobis(seed, n, k, m):
    rng = np.random.default_rng(seed)
    zhat = rng.uniform(0, 1000, (n, m))
    A = rng.normal(size=(n, m, m)) * 30
    S = A @ np.swapaxes(A, -1, -2) + 100 * np.eye(m)
    B = rng.normal(size=(k, m, m)) * 10
    R = B @ np.swapaxes(B, -1, -2) + 10 * np.eye(m)
    z = rng.uniform(0, 1000, (k, m))
    G = gate_threshold(0.99, m)
    g = gate(zhat, S, z, R, G)
    expected = {}
    for i in range(n):
        for j in range(k):
            Sij = S[i] + R[j]
            nu = z[j] - zhat[i]
            d2 = nu @ np.linalg.inv(Sij) @ nu
            if d2 <= G:
                expected[(i, j)] = d2 + np.log(np.linalg.det(Sij))
    got = {(int(i), int(j)): c for i, j, c in zip(g.state, g.plot, g.cost)}
    assert got.keys() == expected.keys()
    for key, c in expected.items():
        assert got[key] == pytest.approx(c, rel=1e-9, abs=1e-9)
    assert g.n_pregated >= len(got)


def _brute_force(cost, miss):
    n, k = cost.shape
    best = np.inf
    for choice in itertools.product(range(-1, k), repeat=n):
        used = [c for c in choice if c >= 0]
        if len(used) != len(set(used)):
            continue
        total = sum(miss[i] if c < 0 else cost[i, c] for i, c in enumerate(choice))
        best = min(best, total)
    return best


def _random_problem(seed, n, k, p_forbid):
    rng = np.random.default_rng(seed)
    cost = rng.uniform(-5, 20, (n, k))
    cost[rng.uniform(size=(n, k)) < p_forbid] = np.inf
    miss = rng.uniform(0, 25, n)
    return cost, miss


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 9), st.integers(0, 9), st.floats(0, 0.8))
def test_auction_equals_jv_on_random_problems(seed, n, k, p_forbid):
    cost, miss = _random_problem(seed, n, k, p_forbid)
    a = assign_auction(cost, miss)
    j = assign_jv(cost, miss)
    # ε-complementary slackness: within (n + k)·ε_final = EPS_FINAL_RELATIVE·C of the optimum
    C = max(1.0, np.abs(cost[np.isfinite(cost)]).max(initial=0), miss.max())
    assert abs(a.total_cost - j.total_cost) <= EPS_FINAL_RELATIVE * C
    for res in (a, j):
        t, p = res.pairs
        assert len(set(p.tolist())) == p.size  # one track per plot
        assert np.isfinite(cost[t, p]).all()  # never a forbidden pair
        assert res.total_cost == pytest.approx(total_cost(cost, miss, res.track_to_plot))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 5), st.integers(0, 5))
def test_both_solvers_reach_the_brute_force_optimum(seed, n, k):
    cost, miss = _random_problem(seed, n, k, 0.3)
    best = _brute_force(cost, miss)
    assert assign_jv(cost, miss).total_cost == pytest.approx(best, abs=1e-7)
    C = max(1.0, np.abs(cost[np.isfinite(cost)]).max(initial=0), miss.max())
    assert assign_auction(cost, miss).total_cost == pytest.approx(best, abs=EPS_FINAL_RELATIVE * C)


def test_split_clusters_finds_connected_components():
    track = np.array([0, 0, 1, 3, 4])
    plot = np.array([0, 1, 1, 2, 2])
    cl = split_clusters(track, plot, 5, 4)
    got = sorted((tuple(t.tolist()), tuple(p.tolist())) for t, p in cl)
    assert got == [((0, 1), (0, 1)), ((3, 4), (2,))]
