"""SIR, SIS and APF steps (Arulampalam et al. 2002) against the Kalman filter on a
scalar linear-Gaussian model, and PF vs EKF on the nonlinear growth-model benchmark.

Linear-Gaussian check: C = 200 independent clouds of N = 2000 particles filter the same
observations. Bounds: the mean over clouds of (PF mean − KF mean) within 5 standard
errors of the cloud-to-cloud spread; each cloud's RMS deviation from the KF mean below
5 √(P/N) (Monte Carlo error of a mean from N particles, with a factor for resampling
noise); the PF variance averaged over clouds within 3 % of P_{k|k}."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.particles import pcrlb
from skyfuse.fusion.particles.auxiliary import apf_step
from skyfuse.fusion.particles.nonlinear_benchmark import ScalarBenchmark, ekf_run
from skyfuse.fusion.particles.roughening import roughen, roughening_sigma
from skyfuse.fusion.particles.sir import sir_step
from skyfuse.fusion.particles.sis import sis_step

A, Q, R = 0.9, 0.5, 1.0
C, N, STEPS = 200, 2000, 8


@dataclass
class _AR1:
    """x_k = a x_{k−1} + N(0, q), y = x + N(0, r)."""

    def mean_transition(self, x, k):
        return A * x

    def propagate(self, x, k, rng):
        return A * x + np.sqrt(Q) * rng.standard_normal(x.shape)

    def log_likelihood(self, x, y, k):
        return -0.5 * (y[:, None, 0] - x[..., 0]) ** 2 / R


def _kalman(ys, m0, p0):
    """Scalar Kalman filter written from the textbook recursion (independent reference)."""
    m, p, out = m0, p0, []
    for y in ys:
        m, p = A * m, A * A * p + Q
        k = p / (p + R)
        m, p = m + k * (y - m), (1 - k) * p
        out.append((m, p))
    return out


def _run(step, **kw):
    rng = np.random.default_rng(42)
    truth = np.cumsum(rng.standard_normal(STEPS))
    ys = truth + rng.standard_normal(STEPS)
    x = 1.0 + np.sqrt(2.0) * rng.standard_normal((C, N, 1))
    w = np.full((C, N), 1.0 / N)
    results = []
    for k, y in enumerate(ys, start=1):
        r = step(_AR1(), x, w, np.full((C, 1), y), k, rng, **kw)
        x, w = r.x, r.w
        results.append(r)
    return results, _kalman(ys, 1.0, 2.0)


def _sir(model, x, w, y, k, rng):
    return sir_step(model, x, y, k, rng)


@pytest.mark.parametrize(
    ("step", "kw"),
    [(_sir, {}), (sis_step, {"threshold": N / 2}), (apf_step, {})],
    ids=["sir", "sis", "apf"],
)
def test_linear_gaussian_posterior_matches_kalman(step, kw):
    results, kf = _run(step, **kw)
    for r, (m, p) in zip(results, kf):
        dev = r.mean[:, 0] - m
        assert abs(dev.mean()) <= 5 * dev.std(ddof=1) / np.sqrt(C) + 1e-12
        assert np.sqrt(np.mean(dev**2)) <= 5 * np.sqrt(p / N)
        assert abs(r.cov[:, 0, 0].mean() / p - 1) < 0.03


def test_sis_resamples_only_below_threshold():
    never, _ = _run(sis_step, threshold=0.0)
    always, _ = _run(sis_step, threshold=N + 1.0)
    assert not any(r.resampled.any() for r in never)
    assert all(r.resampled.all() for r in always)
    assert np.allclose(always[-1].w, 1.0 / N)


def test_roughening_sigma_and_spread():
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, [1.0, 10.0], size=(3, 400, 2))
    s = roughening_sigma(x, K=0.2)
    spread = x.max(axis=1) - x.min(axis=1)
    assert np.allclose(s, 0.2 * spread / 20.0)  # N^(-1/2) = 1/20
    d = roughen(x, rng, K=0.2) - x
    assert np.allclose(d.std(axis=1), s, rtol=0.15)
    assert roughen(x, rng, K=0.0) is x


def test_pf_beats_ekf_on_the_scalar_nonlinear_benchmark():
    """The nonlinear benchmark: 40 runs × 50 steps, SIR with N = 1000. Per-run MSEs are paired; the
    EKF − PF differences are heavy-tailed (EKF divergences), so the bound is a one-sided
    Wilcoxon signed-rank test at p < 1e-3, plus overall RMSE(PF) < 0.8 RMSE(EKF). The PF's
    MSE must stay above 0.9 × the PCRLB (Tichavský recursion along the true trajectories)."""
    model, runs, steps = ScalarBenchmark(), 40, 50
    rng = np.random.default_rng(2016)
    xs, ys = model.simulate(runs, steps, rng)
    ekf = ekf_run(model, ys, P0=1.0)
    x = model.x0 + rng.standard_normal((runs, 1000, 1))
    pf = np.empty_like(xs)
    for k in range(1, steps + 1):
        r = sir_step(model, x, ys[:, k - 1 : k], k, rng)
        x, pf[:, k - 1] = r.x, r.mean[:, 0]
    mse_ekf = ((ekf - xs) ** 2).mean(axis=1)
    mse_pf = ((pf - xs) ** 2).mean(axis=1)
    assert stats.wilcoxon(mse_ekf, mse_pf, alternative="greater").pvalue < 1e-3
    assert np.sqrt(mse_pf.mean()) < 0.8 * np.sqrt(mse_ekf.mean())
    prev = np.concatenate([np.full((runs, 1), model.x0), xs[:, :-1]], axis=1)
    bound = pcrlb.additive_gaussian(
        np.ones((1, 1)),
        model.df(prev)[..., None, None],
        model.dh(xs)[..., None, None],
        np.array([[model.q]]),
        np.array([[model.r]]),
    )
    assert mse_pf.mean() >= 0.9 * bound[:, 0, 0].mean()
