"""Resampling schemes ([thesis] (3.51–3.55) and others) against closed forms, many clouds per call.

Each scheme resamples the same weights in n = 4000 clouds at once. Offspring counts N_i
must be unbiased (E N_i = N w_i) and have the closed-form variance of the scheme
(systematic f(1 − f); stratified Σ_l a_l(1 − a_l); multinomial N w(1 − w); residual
R w̄(1 − w̄)); sample means and variances are compared within 5 standard errors (the
variance's standard error from the sample fourth moment). The resampled cloud's mean of a
test function must match the weighted mean within 5 standard errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.particles import resampling
from skyfuse.fusion.particles.weights import effective_sample_size

N = 40
CLOUDS = 4000


def _weights() -> np.ndarray:
    rng = np.random.default_rng(7)
    w = rng.gamma(0.6, size=N)
    w[[3, 17, 30]] = 0.0  # never chosen
    w[5] = 6.0 * w.sum() / N  # one heavy particle, N w > 1
    return w / w.sum()


def _stratified_var(w: np.ndarray) -> np.ndarray:
    """Σ_l a_l (1 − a_l), a_l = |[l, l+1) ∩ [N c_{i−1}, N c_i)| (brute force)."""
    c = np.concatenate([[0.0], np.cumsum(w)]) * len(w)
    var = np.zeros(len(w))
    for i in range(len(w)):
        for layer in range(len(w)):
            a = max(0.0, min(c[i + 1], layer + 1) - max(c[i], layer))
            var[i] += a * (1 - a)
    return var


def _closed_form_var(scheme: str, w: np.ndarray) -> np.ndarray:
    Nw = len(w) * w
    if scheme == "systematic":
        f = Nw - np.floor(Nw)
        return f * (1 - f)
    if scheme == "stratified":
        return _stratified_var(w)
    if scheme == "multinomial":
        return Nw * (1 - w)
    R = len(w) - np.floor(Nw).sum()
    wbar = (Nw - np.floor(Nw)) / R
    return R * wbar * (1 - wbar)


@pytest.mark.parametrize("scheme", sorted(resampling.SCHEMES))
def test_offspring_counts_unbiased_with_closed_form_variance(scheme):
    w = _weights()
    W = np.tile(w, (CLOUDS, 1))
    idx = resampling.resample(W, np.random.default_rng(11), scheme)
    assert idx.shape == (CLOUDS, N)
    assert (np.diff(idx, axis=1) >= 0).all()
    counts = np.stack([np.bincount(row, minlength=N) for row in idx]).astype(float)
    assert (counts.sum(axis=1) == N).all()
    assert (counts[:, [3, 17, 30]] == 0).all()
    mean, var = counts.mean(axis=0), counts.var(axis=0, ddof=1)
    v = _closed_form_var(scheme, w)
    assert np.all(np.abs(mean - N * w) <= 5 * np.sqrt(v / CLOUDS) + 1e-12)
    m4 = ((counts - mean) ** 4).mean(axis=0)
    # rare offspring (N w ≪ 1) may never occur in the sample: floor the standard error by
    # the Poisson-limit value √(v/n) (μ4 ≈ v for a count that is almost always 0)
    se_var = np.sqrt(np.maximum(m4 - var**2, v) / CLOUDS)
    assert np.all(np.abs(var - v) <= 5 * se_var + 1e-9)


@pytest.mark.parametrize("scheme", sorted(resampling.SCHEMES))
def test_resampled_mean_matches_weighted_mean(scheme):
    w = _weights()
    x = np.linspace(-3.0, 5.0, N) ** 2
    idx = resampling.resample(np.tile(w, (CLOUDS, 1)), np.random.default_rng(3), scheme)
    means = x[idx].mean(axis=1)
    se = means.std(ddof=1) / np.sqrt(CLOUDS)
    assert abs(means.mean() - w @ x) <= 5 * se + 1e-12
    if scheme == "multinomial":  # i.i.d. draws: Var of the mean = Var_w(x)/N (chi-square)
        var_w = w @ (x - w @ x) ** 2 / N
        lo, hi = stats.chi2.ppf([1e-4, 1 - 1e-4], CLOUDS - 1) / (CLOUDS - 1)
        assert lo * var_w <= means.var(ddof=1) <= hi * var_w


def test_ordered_uniforms_are_sorted_uniform_samples():
    u = resampling.ordered_uniforms(np.random.default_rng(5), 300, 50)
    assert (np.diff(u, axis=1) >= 0).all()
    assert stats.kstest(u.ravel(), "uniform").pvalue > 1e-4
    # the largest of 50 uniforms has cdf x^50
    assert stats.kstest(u[:, -1] ** 50, "uniform").pvalue > 1e-4


def test_each_cloud_uses_its_own_weights():
    rng = np.random.default_rng(2)
    W = np.zeros((6, 10))
    W[np.arange(6), [0, 9, 4, 4, 2, 7]] = 1.0
    for scheme in resampling.SCHEMES:
        idx = resampling.resample(W, rng, scheme)
        assert (idx == np.array([0, 9, 4, 4, 2, 7])[:, None]).all(), scheme


def test_effective_sample_size_limits():
    w = np.array([[0.25] * 4, [1.0, 0, 0, 0], [0.5, 0.5, 0, 0]])
    assert np.allclose(effective_sample_size(w), [4.0, 1.0, 2.0])


def test_unknown_scheme_is_rejected():
    with pytest.raises(ValueError, match="scheme"):
        resampling.resample(np.ones((1, 3)) / 3, np.random.default_rng(0), "bogus")
