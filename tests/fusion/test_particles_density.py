"""ParticleDensity ([LM-IPF]) against independent references: a Kalman filter for one
track without clutter, scipy's multivariate normal for the per-plot likelihoods, brute
force for the moment-matched gate, and a single-target IPDA loop written here from the
thesis's formulas ([thesis] §2.3.1, §3.4: Λ, β, ψ with P_D, P_G, ρ).

Kalman bound: T = 100 identical converged tracks × N = 2000 particles get the same plots;
per scan and state component the mean over tracks of (PF − KF) lies within 5 standard
errors of the track-to-track spread; the RMS deviation over tracks stays below
5 √(P_ii/ESS) with ESS = 1/Σw² of that scan's update (the Monte Carlo error of an
importance-weighted mean; measured ratios ≤ 2.5 include the error carried from earlier
scans); the PF variance averaged over tracks is within 8 % of the Kalman P_ii (a weighted
variance from ESS ≥ 150 scatters by √(2/ESS) ≈ 12 % per cloud, and resampling makes
clouds slightly under-dispersed)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.filters import kalman
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.particles.likelihood import pair_likelihoods
from skyfuse.fusion.tracker.density.particles import ParticleDensity
from skyfuse.fusion.tracker.store import NewTracks, store_for

CV = ConstantVelocity(q=0.75, ndim=2)
P0 = np.diag([25.0, 100.0, 25.0, 100.0])
X0 = np.array([100.0, 20.0, -50.0, 5.0])
R = np.array([[25.0, 6.0], [6.0, 16.0]])
G99 = stats.chi2.ppf(0.99, 2)


def _plots(rng, steps, dt=1.0):
    x, out = X0.copy(), []
    for _ in range(steps):
        x = CV.F(dt) @ x
        out.append(x[[0, 2]] + rng.multivariate_normal(np.zeros(2), R))
    return out


def _steady_covariance(scans=30):
    """P_{k|k} of the Kalman filter after ``scans`` updates from P0 (a converged track:
    from the diffuse P0 a particle cloud's velocity spread collapses onto few ancestors
    within 3 scans, because the CV process noise rejuvenates velocity only by q T)."""
    P = P0[None]
    x = X0[None]
    for _ in range(scans):
        x, P = kalman.predict(x, P, CV.F(1.0), CV.Q(1.0))
        x, P, _, _ = kalman.update(x, P, x @ CV.H().T, CV.H(), R)
    return P[0]


@pytest.mark.parametrize("neff_threshold", [None, 0.5])
def test_one_track_no_clutter_matches_kalman(neff_threshold):
    T, N = 100, 2000
    dens = ParticleDensity(CV, N, neff_threshold=neff_threshold, seed=1)
    store_for(dens)
    P1 = _steady_covariance()
    dens.tracks.append(NewTracks(np.tile(X0, (T, 1)), np.tile(P1, (T, 1, 1))))
    x, P = X0[None], P1[None]
    rows = np.arange(T)
    for z in _plots(np.random.default_rng(3), 6):
        pred = dens.predict(rows, np.ones(T))
        table = dens.likelihoods(pred, z[None], R[None], stats.chi2.ppf(0.9999, 2))
        assert len(table) == T  # P_D = 1, no clutter: β_0 = 0, β = 1
        w_post = pred.w * table.lik
        w_post /= w_post.sum(axis=1, keepdims=True)
        ess = 1.0 / (w_post**2).sum(axis=1)
        dens.update(pred, table, np.zeros(T), np.ones(T))
        x, P = kalman.predict(x, P, CV.F(1.0), CV.Q(1.0))
        x, P, _, _ = kalman.update(x, P, z[None], CV.H(), R)
        mean, cov = dens.estimate(rows)
        dev = mean - x
        var = np.diagonal(P[0])
        assert np.all(np.abs(dev.mean(0)) <= 5 * dev.std(0, ddof=1) / np.sqrt(T) + 1e-12)
        assert np.all(np.sqrt((dev**2).mean(0)) <= 5 * np.sqrt(var / ess.min()))
        assert np.allclose(np.diagonal(cov, axis1=1, axis2=2).mean(0), var, rtol=0.08)


def test_pair_likelihoods_use_each_plots_own_covariance():
    rng = np.random.default_rng(0)
    zp = rng.normal(size=(2, 5, 2)) * 10
    z = rng.normal(size=(3, 2)) * 10
    A = rng.normal(size=(3, 2, 2))
    Rs = A @ np.swapaxes(A, 1, 2) + np.eye(2) * 4
    tp_track, tp_plot = np.array([0, 0, 1]), np.array([0, 2, 1])
    got = pair_likelihoods(zp, z, Rs, tp_track, tp_plot)
    for row, (t, j) in enumerate(zip(tp_track, tp_plot)):
        ref = stats.multivariate_normal(z[j], Rs[j]).pdf(zp[t])
        assert np.allclose(got[row], ref, rtol=1e-12)


def test_gate_uses_moment_matched_cloud_and_track_likelihood_is_weighted_sum():
    rng = np.random.default_rng(5)
    dens = ParticleDensity(CV, 500, seed=2)
    store_for(dens)
    dens.tracks.append(
        NewTracks(X0 + np.array([[0.0, 0, 0, 0], [400.0, 0, 0, 0]]), np.tile(P0, (2, 1, 1)))
    )
    pred = dens.predict(np.arange(2), np.array([1.0, 2.0]))
    z = np.array(X0[[0, 2]] + [20, 0]) + rng.normal(size=(60, 2)) * 40
    Rs = np.tile(R, (60, 1, 1))
    table = dens.likelihoods(pred, z, Rs, G99)
    pairs = set()
    for t in range(2):
        xs = pred.x[t][:, [0, 2]]
        mu = pred.w[t] @ xs
        S = np.cov(xs.T, aweights=pred.w[t], bias=True) + R
        for j in range(60):
            nu = z[j] - mu
            if nu @ np.linalg.solve(S, nu) < G99:
                pairs.add((t, j))
    assert set(zip(table.tp_track.tolist(), table.tp_plot.tolist())) == pairs
    for row, (t, j) in enumerate(zip(table.tp_track, table.tp_plot)):
        pdf = stats.multivariate_normal(z[j], R).pdf(pred.x[t][:, [0, 2]])
        assert np.isclose(table.p[row], pred.w[t] @ pdf / 0.99, rtol=1e-9)


def _ipda_run(dens, plots_per_scan, rho, pd=0.9, p11=0.98, psi0=0.5):
    """Single-target IPDA existence loop from [thesis] §2.3.1 / §3.4 formulas."""
    psi, pg = psi0, 0.99
    history = []
    for z in plots_per_scan:
        psi_pred = p11 * psi
        pred = dens.predict(np.array([0]), np.array([1.0]))
        table = dens.likelihoods(pred, z, np.tile(R, (len(z), 1, 1)), G99)
        ratio = table.p / rho
        lam = 1 - pd * pg + pd * pg * ratio.sum()
        psi = lam * psi_pred / (1 - (1 - lam) * psi_pred)
        beta0 = np.array([(1 - pd * pg) / lam])
        beta = pd * pg * ratio / lam
        dens.update(pred, table, beta0, beta)
        history.append(psi)
    return np.array(history)


def _clutter(rng, centre, rho, half=300.0):
    n = rng.poisson(rho * (2 * half) ** 2)
    return centre + rng.uniform(-half, half, size=(n, 2))


def test_ipda_loop_confirms_on_a_target_and_decays_on_clutter():
    rng = np.random.default_rng(8)
    rho = 2e-5  # plots per m²
    truth = _plots(rng, 25)
    scans = []
    for z in truth:
        c = _clutter(rng, z, rho)
        scans.append(np.vstack([c, z[None]]) if rng.random() < 0.9 else c)
    dens = ParticleDensity(CV, 1000, seed=4)
    store_for(dens)
    dens.tracks.append(NewTracks(X0[None], P0[None]))
    psi_target = _ipda_run(dens, scans, rho)
    assert psi_target[-1] > 0.99 and psi_target[5:].min() > 0.9
    err = dens.estimate([0])[0][0, [0, 2]] - CV.F(25.0) @ X0 @ np.eye(4)[:, [0, 2]]
    assert np.hypot(*err) < 30.0
    dens = ParticleDensity(CV, 1000, seed=4)
    store_for(dens)
    dens.tracks.append(NewTracks(X0[None], P0[None]))
    centre = X0[[0, 2]]
    psi_clutter = _ipda_run(dens, [_clutter(rng, centre, rho) for _ in range(25)], rho)
    assert psi_clutter[-1] < 0.05


def test_add_keep_and_three_dimensional_positions():
    cv3 = ConstantVelocity(q=1.0, ndim=3)
    dens = ParticleDensity(cv3, 300, seed=0)
    store_for(dens)
    assert dens.dim == 6 and len(dens) == 0
    x = np.array([[0, 1, 0, 2, 1000, 0], [5e3, 0, 5e3, 0, 2000, 0]], float)
    dens.tracks.append(NewTracks(x, np.tile(np.eye(6) * 9.0, (2, 1, 1))))
    dens.tracks.append(NewTracks(x[:1] + 1e4, np.eye(6)[None] * 9.0))
    assert len(dens) == 3 and dens.tracks.particles.shape == (3, 300, 6)
    dens.tracks.keep(np.array([True, False, True]))
    assert len(dens) == 2
    assert np.allclose(dens.estimate([1])[0], x[:1] + 1e4)
    pred = dens.predict(np.array([0, 1]), np.array([1.0, 4.0]))
    assert pred.z_mean.shape == (2, 3) and pred.S0.shape == (2, 3, 3)
    z = np.array([[1.0, 2.0, 1000.0]])
    table = dens.likelihoods(pred, z, np.eye(3)[None] * 25.0, stats.chi2.ppf(0.99, 3))
    assert table.tp_track.tolist() == [0] and table.lik.shape == (1, 300)
    dens.update(pred, table, np.array([0.5, 1.0]), np.array([0.5]))
    assert np.allclose(dens.tracks.weights.sum(axis=1), 1.0)


def test_update_weights_follow_a14_before_resampling():
    """Stored MMSE = Σ w_j x_j with w_j ∝ w_j (β_0 + Σ_i β_i p_i(x_j)/p_i) ([LM-IPF] eq. 11, 13),
    evaluated here with explicit loops over plots and particles."""
    rng = np.random.default_rng(9)
    dens = ParticleDensity(CV, 60, seed=5)
    store_for(dens)
    dens.tracks.append(NewTracks(np.array([X0, X0 + 30.0]), np.tile(P0, (2, 1, 1))))
    pred = dens.predict(np.array([1, 0]), np.array([1.0, 0.5]))
    z = np.vstack([X0[[0, 2]] + rng.normal(size=(3, 2)) * 5, X0[[0, 2]] + 45.0])
    table = dens.likelihoods(pred, z, np.tile(R, (4, 1, 1)), G99)
    beta0 = np.array([0.2, 0.35])
    beta = rng.uniform(0.05, 0.3, len(table))
    dens.update(pred, table, beta0, beta)
    for t in range(2):
        w = pred.w[t].copy()
        for j in range(60):
            factor = beta0[t]
            for r in range(len(table)):
                if table.tp_track[r] == t:
                    factor += beta[r] * table.lik[r, j] / table.p[r]
            w[j] *= factor
        w /= w.sum()
        mean, cov = dens.estimate([pred.rows[t]])
        assert np.allclose(mean[0], w @ pred.x[t], rtol=1e-12)
        dx = pred.x[t] - w @ pred.x[t]
        assert np.allclose(cov[0], (w[:, None] * dx).T @ dx, rtol=1e-9)
    assert np.allclose(dens.tracks.weights, 1.0 / 60)  # resampled every scan by default


def test_neff_threshold_resamples_only_degenerate_rows_and_edge_cases():
    dens = ParticleDensity(CV, 200, neff_threshold=0.5, seed=1)
    store_for(dens)
    dens.tracks.append(NewTracks(np.array([X0, X0 + 5e3]), np.tile(P0, (2, 1, 1))))
    pred = dens.predict(np.arange(2), np.ones(2))
    table = dens.likelihoods(pred, (X0[[0, 2]] + [20.0, 0.0])[None], R[None], G99)
    assert table.tp_track.tolist() == [0]
    dens.update(pred, table, np.array([0.0, 1.0]), np.array([1.0]))
    assert np.allclose(dens.tracks.weights[0], 1 / 200)  # informative plot: N_eff < N/2
    assert np.array_equal(
        dens.tracks.particles[1], pred.x[1]
    )  # β_0 = 1: prior cloud kept as predicted
    empty = dens.predict(np.zeros(0, np.int64), np.zeros(0))
    t0 = dens.likelihoods(empty, np.zeros((0, 2)), np.zeros((0, 2, 2)), G99)
    assert len(t0) == 0 and empty.z_mean.shape == (0, 2)
    still = dens.predict(np.arange(2), np.zeros(2))  # dt = 0: no motion, no noise
    assert np.array_equal(still.x, dens.tracks.particles)
    with pytest.raises(ValueError, match="scheme"):
        ParticleDensity(CV, 10, scheme="nope")
    with pytest.raises(ValueError, match="neff_threshold"):
        ParticleDensity(CV, 10, neff_threshold=1.5)


def test_pair_likelihoods_blocks_give_the_same_table(monkeypatch):
    from skyfuse.fusion.particles import likelihood

    rng = np.random.default_rng(1)
    zp, z = rng.normal(size=(4, 50, 2)), rng.normal(size=(6, 2))
    Rs = np.tile(np.eye(2), (6, 1, 1))
    t, j = np.repeat(np.arange(4), 6), np.tile(np.arange(6), 4)
    whole = likelihood.pair_likelihoods(zp, z, Rs, t, j)
    monkeypatch.setattr(likelihood, "BLOCK", 120)  # 2 pairs per block, last one short
    assert np.array_equal(likelihood.pair_likelihoods(zp, z, Rs, t, j), whole)


@pytest.mark.parametrize("ndim", [2, 3])
def test_prediction_spread_is_q(ndim):
    """A point-mass cloud predicted over dt has sample covariance Q(dt) (Bartlett bound:
    each entry within 5 √((Q_ii Q_jj + Q_ij²)/N)) and mean F x."""
    cv = ConstantVelocity(q=2.0, ndim=ndim, q_vertical=0.1 if ndim == 3 else None)
    N, dt = 20000, 3.0
    dens = ParticleDensity(cv, N, seed=6)
    store_for(dens)
    x = np.arange(1.0, cv.dim + 1)
    dens.tracks.append(NewTracks(x[None], np.zeros((1, cv.dim, cv.dim))))
    pred = dens.predict(np.array([0]), np.array([dt]))
    Q = cv.Q(dt)
    tol = 5 * np.sqrt((np.outer(np.diag(Q), np.diag(Q)) + Q**2) / N)
    assert np.all(np.abs(pred.P[0] - Q) <= tol)
    assert np.all(np.abs(pred.x_mean[0] - cv.F(dt) @ x) <= 5 * np.sqrt(np.diag(Q) / N))


def test_roughening_in_the_density_spreads_duplicates():
    dens = ParticleDensity(CV, 400, roughening=0.2, seed=3)
    store_for(dens)
    dens.tracks.append(NewTracks(X0[None], P0[None]))
    pred = dens.predict(np.array([0]), np.array([1.0]))
    table = dens.likelihoods(pred, (CV.F(1.0) @ X0)[[0, 2]][None], R[None], G99)
    dens.update(pred, table, np.zeros(1), np.ones(1))
    assert len(np.unique(dens.tracks.particles[0][:, 0])) == 400  # no duplicated ancestors left
