"""BiasFilter's batch update (the compiled gate and information update of
:mod:`fusion.registration.bias_filter_kernel`) against an independent reference: for a
static state the information update of a batch of pairs equals the sequential Kalman
updates of the same pairs one by one, written here with dense NumPy algebra (Bar-Shalom,
Li & Kirubarajan 2001, §7.2); and the gate against the χ² bound computed here."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2
from skyfuse.fusion.registration.bias_filter import BiasFilter
from skyfuse.fusion.registration.common_target import ResidualPairs

SIGMA0 = np.array([1e-3, 50.0, 1e-4, 0.5])  # rad, m, 1, s


def _filter(estimated=(True, True, True, False), p_gate=0.999) -> BiasFilter:
    f = BiasFilter(SIGMA0, np.array(estimated), p_gate)
    for reference in (True, False, False):
        f.add_radar(reference)
    return f


def _pairs(rng, k: int, scale: float = 1.0) -> ResidualPairs:
    a = rng.integers(0, 3, k)
    b = (a + rng.integers(1, 3, k)) % 3
    HA, HB = rng.normal(0, 1, (k, 2, 4)), rng.normal(0, 1, (k, 2, 4))
    L = rng.normal(0, 1, (k, 2, 2))
    W = L @ L.swapaxes(1, 2) + 0.5 * np.eye(2)
    y = scale * rng.normal(0, 1, (k, 2))
    return ResidualPairs(y, W, HA, HB, a, b, np.zeros(k, np.int64))


def _h(f: BiasFilter, p: ResidualPairs, j: int) -> np.ndarray:
    """Pair j's rows of eq. (1) in normalised units, fixed columns zero (2, 4n)."""
    H = np.zeros((2, 4 * f.n_radars))
    H[:, 4 * p.a[j] : 4 * p.a[j] + 4] += p.HA[j] * SIGMA0
    H[:, 4 * p.b[j] : 4 * p.b[j] + 4] -= p.HB[j] * SIGMA0
    return H * f._free_rows().reshape(-1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batch_update_equals_sequential_kalman_updates(seed):
    rng = np.random.default_rng(seed)
    f = _filter(p_gate=1 - 1e-12)
    p = _pairs(rng, 25, scale=1e-3)  # small residuals: every pair passes the gate
    s, P = f.s.copy(), f.P.copy()
    for j in range(len(p)):
        H = _h(f, p, j)
        S = H @ P @ H.T + p.W[j]
        K = P @ H.T @ np.linalg.inv(S)
        s = s + K @ (p.y[j] - H @ s)
        P = (np.eye(len(s)) - K @ H) @ P
    assert f.update(p) == len(p)
    np.testing.assert_allclose(f.s, s, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(f.P, 0.5 * (P + P.T), rtol=1e-9, atol=1e-12)
    assert (f.s[:4] == 0).all() and (f.P[:4] == 0).all()  # the reference stays fixed
    assert (f.s[4 * np.arange(1, 3) + 3] == 0).all()  # b_t not estimated
    used = np.bincount(p.a, minlength=3) + np.bincount(p.b, minlength=3)
    assert f.pairs_used.tolist() == used.tolist()


def test_pairs_outside_the_gate_are_counted_and_not_used():
    rng = np.random.default_rng(5)
    f = _filter()
    p = _pairs(rng, 40, scale=30.0)
    s0, P0 = f.s.copy(), f.P.copy()
    d2 = np.array([
        (p.y[j] @ np.linalg.solve(_h(f, p, j) @ P0 @ _h(f, p, j).T + p.W[j], p.y[j]))
        for j in range(len(p))
    ])  # fmt: skip
    inside = d2 <= chi2.ppf(0.999, 2)
    assert 0 < inside.sum() < len(p)  # the case tests both sides of the gate
    assert f.update(p) == int(inside.sum())
    assert f.pairs_rejected.tolist() == np.bincount(p.a[~inside], minlength=3).tolist()
    ref = _filter()
    kept = ResidualPairs(p.y[inside], p.W[inside], p.HA[inside], p.HB[inside],
                         p.a[inside], p.b[inside], p.time[inside])  # fmt: skip
    assert ref.update(kept) == int(inside.sum())
    np.testing.assert_allclose(f.s, ref.s, rtol=1e-12, atol=1e-15)
    assert not np.array_equal(f.s, s0) and not np.array_equal(f.P, P0)


def test_pairs_of_reference_radars_only_change_nothing():
    f = _filter()
    rng = np.random.default_rng(3)
    p = _pairs(rng, 5)
    p.a[:], p.b[:] = 0, 0  # no free component in any pair: not informative
    assert f.update(p) == 0
    assert (f.s == 0).all() and f.pairs_rejected.sum() == 0 and f.pairs_used.sum() == 0
