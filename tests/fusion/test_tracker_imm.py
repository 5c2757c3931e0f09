"""IMM inside the existence trackers (IMM-IPDA / IMM-ITS / IMM-LM-ITS / IMM-JITS).

References: the single-mode IMM equals the Gaussian-mixture density (IPDA/ITS/…) on the
same plots; the mode probabilities and existence of a two-model IMM-IPDA equal a
hand-written per-axis scalar recursion ([Dikić] eq. 15-19 with IPDA β, [thesis] (5.16)-(5.18));
IMM-CV-CT beats CV during a 3 g turn; the transition matrix power composes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.models import ConstantVelocity
from skyfuse.fusion.tracker import MeasurementBatch, SectorCoverage, Tracker, TrackerConfig
from skyfuse.fusion.tracker.density import TrackDensity
from skyfuse.fusion.tracker.density.imm_mixture import IMMMixtureDensity, ModeTransition

NS = 10**9


def _scene(ndim, seed, steps=30, n_targets=6, clutter=40, side=20_000.0):
    rng = np.random.default_rng(seed)
    x0 = rng.uniform(0, side, (n_targets, ndim))
    v = rng.normal(0, 80, (n_targets, ndim))
    batches = []
    for k in range(1, steps):
        pos = x0 + v * 2 * k
        det = rng.random(n_targets) < 0.9
        z = pos[det] + rng.normal(0, 30, (int(det.sum()), ndim))
        c = rng.uniform(0, side, (rng.poisson(clutter), ndim))
        rho = clutter / side**ndim
        zz = np.concatenate([z, c])
        batches.append(MeasurementBatch(2 * k * NS, "r", zz, 900.0 * np.eye(ndim), 0.9, rho))
    return batches


@pytest.mark.parametrize("kind", ["ipda", "its", "lmits", "jits", "gnn"])
@pytest.mark.parametrize("ndim", [2, 3])
def test_single_mode_imm_equals_gaussian_mixture(kind, ndim):
    batches = _scene(ndim, 3 + ndim)
    cfg = TrackerConfig(
        tracker=kind, motion="cv", ndim=ndim, clutter="estimated", v_max=300.0, depth=2
    )
    one_mode = IMMMixtureDensity(
        [ConstantVelocity(q=cfg.q, ndim=ndim)], ModeTransition([[1.0]], 4.0), [1.0], ndim,
        cfg.memory_depth, cfg.prune_threshold, cfg.max_components,
    )  # fmt: skip
    ref, imm = Tracker(cfg), Tracker(cfg, density=one_mode)
    assert isinstance(imm.density, TrackDensity)
    for b in batches:
        a, c = ref.step(b), imm.step(b)
        np.testing.assert_array_equal(a.ids, c.ids)
        np.testing.assert_allclose(c.states, a.states, rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(c.existence, a.existence, rtol=1e-9, atol=1e-12)
    assert a.confirmed.sum() >= 5


def _cv_predict(m, P, T, q):
    """[x, vx, y, vy] CV prediction written out ([MZD] eq. 5-7)."""
    f = np.array([[1.0, T], [0.0, 1.0]])
    g = q * np.array([[T**4 / 4, T**3 / 2], [T**3 / 2, T**2]])
    F, Q = np.zeros((4, 4)), np.zeros((4, 4))
    F[:2, :2] = F[2:, 2:] = f
    Q[:2, :2] = Q[2:, 2:] = g
    return F @ m, F @ P @ F.T + Q


def _gauss(nu, S):
    return math.exp(-0.5 * nu @ np.linalg.solve(S, nu)) / (
        2 * math.pi * math.sqrt(np.linalg.det(S))
    )


def test_two_model_mode_probabilities_match_hand_written_recursion():
    """One track, one plot per scan, IPDA β; two CV modes (q = 1 and 400 m²/s⁴) with
    Π per 4 s = [[0.9, 0.1], [0.2, 0.8]]; the loop-by-loop reference below ([Dikić]
    eq. 15-19, [thesis] (5.16)-(5.18), (2.38)) is independent of the tracker's array code."""
    qs, tpm, T, r, pd, rho = (1.0, 400.0), np.array([[0.9, 0.1], [0.2, 0.8]]), 4.0, 100.0, 0.9, 1e-9
    cfg = TrackerConfig(tracker="ipda", motion="cv", q=1.0, initiation="none", p_gate=0.999999,
                        clutter="known", delta11=1.0)  # fmt: skip
    density = IMMMixtureDensity(
        [ConstantVelocity(q=qq) for qq in qs], ModeTransition(tpm, T), [0.5, 0.5], 2
    )
    tr = Tracker(cfg, density=density)
    x0 = np.array([0.0, 200.0, 0.0, 0.0])
    P0 = np.diag([r, 100.0, r, 100.0])
    tr.add_track(x0, P0, 0, existence=0.5)
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    mean, cov = [x0.copy(), x0.copy()], [P0.copy(), P0.copy()]
    mu, psi = np.array([0.5, 0.5]), 0.5
    pg = 1 - math.exp(-tr.g / 2)
    rng = np.random.default_rng(4)
    for k in range(1, 9):
        acc = 0.0 if k < 4 else 30.0  # a 3 g manoeuvre in y from scan 4
        truth = np.array([200.0 * T * k, 0.5 * acc * (T * max(k - 3, 0)) ** 2])
        z = truth + rng.normal(0, 10, 2)
        tr.step(MeasurementBatch(int(k * T * NS), "r", z[None], r * np.eye(2), pd, rho))
        c = mu @ tpm  # eq. 15
        pred_m, pred_P, N, upd_m, upd_P = [], [], np.zeros(2), [], []
        for j in range(2):
            wts = [mu[i] * tpm[i, j] / c[j] for i in range(2)]  # eq. 16
            m0 = wts[0] * mean[0] + wts[1] * mean[1]
            C0 = sum(w * (cov[i] + np.outer(mean[i] - m0, mean[i] - m0)) for i, w in enumerate(wts))
            mp, Pp = _cv_predict(m0, C0, T, qs[j])
            S = H @ Pp @ H.T + r * np.eye(2)
            N[j] = _gauss(z - H @ mp, S)  # eq. 18
            K = Pp @ H.T @ np.linalg.inv(S)
            pred_m.append(mp)
            pred_P.append(Pp)
            upd_m.append(mp + K @ (z - H @ mp))
            upd_P.append((np.eye(4) - K @ H) @ Pp)
        p = float(c @ N) / pg
        lam = 1 - pd * pg + pd * pg * p / rho  # 5.16
        beta0, beta1 = (1 - pd * pg) / lam, pd * pg * (p / rho) / lam
        psi = lam * psi / (1 - (1 - lam) * psi)  # 5.18
        mu_plot = c * N / (c @ N)  # eq. 19
        mu = beta0 * c + beta1 * mu_plot
        for j in range(2):
            w0, w1 = beta0 * c[j] / mu[j], beta1 * mu_plot[j] / mu[j]
            mm = w0 * pred_m[j] + w1 * upd_m[j]
            d0, d1 = pred_m[j] - mm, upd_m[j] - mm
            cov[j] = w0 * (pred_P[j] + np.outer(d0, d0)) + w1 * (upd_P[j] + np.outer(d1, d1))
            mean[j] = mm
        got = tr.density.mode_probabilities(np.array([0]))[0]
        np.testing.assert_allclose(got, mu, rtol=1e-7, atol=1e-10)
        assert tr.existence()[0] == pytest.approx(psi, rel=1e-9)
        np.testing.assert_allclose(tr.density.comp.x[1][0], mean[1], rtol=1e-7, atol=1e-6)
    assert mu[1] > 0.9  # the manoeuvre mode took over during the turn


def _turn_rmse(motion, seed, ndim=2):
    """RMSE over the scans of a 3 g turn (T = 4 s, 250 m/s, σ = 50 m)."""
    rng = np.random.default_rng(seed)
    cfg = TrackerConfig(tracker="ipda", motion=motion, ndim=ndim, initiation="none")
    tr = Tracker(cfg)
    v, T, w = 250.0, 4.0, 3 * 9.80665 / 250.0
    x = np.zeros(2 * ndim)
    x[1] = v
    tid = tr.add_track(x, np.diag([2500.0, 100.0] * ndim), 0, existence=0.9, confirmed=True)
    p, heading, err = np.zeros(ndim), 0.0, []
    for k in range(1, 30):
        turning = 8 <= k < 18
        for _ in range(40):  # integrate the truth in 0.1 s steps
            heading += (w if turning else 0.0) * T / 40
            p[:2] += v * T / 40 * np.array([math.cos(heading), math.sin(heading)])
        z = p + rng.normal(0, 50, ndim)
        out = tr.step(
            MeasurementBatch(int(k * T * NS), "r", z[None], 2500 * np.eye(ndim), 0.9, 1e-12)
        )
        if tid not in out.ids:
            return math.inf
        i = list(out.ids).index(tid)
        if turning:
            err.append(float(np.sum((out.states[i, 0::2] - p) ** 2)))
    return math.sqrt(np.mean(err))


@pytest.mark.parametrize("ndim", [2, 3])
def test_imm_cv_ct_beats_cv_in_a_turn(ndim):
    cv = np.mean([_turn_rmse("cv", s, ndim) for s in range(3)])
    ct = np.mean([_turn_rmse("imm-cv-ct", s, ndim) for s in range(3)])
    singer = np.mean([_turn_rmse("imm-cv-singer", s, ndim) for s in range(3)])
    assert math.isfinite(ct) and math.isfinite(singer)
    assert ct < 0.9 * cv, (ct, cv)
    assert singer < cv, (singer, cv)


def test_mode_transition_composes_and_rejects_bad_matrices():
    tr = ModeTransition([[0.95, 0.05], [0.1, 0.9]], 4.0)
    P8 = tr(np.array([8.0]))[0]
    np.testing.assert_allclose(P8, np.linalg.matrix_power(tr.tpm, 2), atol=1e-12)
    np.testing.assert_allclose(tr(np.array([0.0]))[0], np.eye(2), atol=1e-12)
    from scipy.linalg import fractional_matrix_power

    tpm3 = np.full((3, 3), 0.05) + 0.85 * np.eye(3)  # eigenvalues 1, 0.85, 0.85
    tr3 = ModeTransition(tpm3, 4.0)
    got = tr3(np.array([1.0, 6.0, 4.0]))
    for k, t in enumerate((1.0, 6.0, 4.0)):
        ref = np.real(fractional_matrix_power(tpm3, t / 4.0))
        np.testing.assert_allclose(got[k], ref, atol=1e-12)
    np.testing.assert_allclose(got.sum(axis=2), 1.0, rtol=1e-15)
    with pytest.raises(ValueError, match="eigenvalues"):
        ModeTransition([[0.1, 0.9], [0.9, 0.1]], 4.0)
    with pytest.raises(ValueError, match="row-stochastic"):
        ModeTransition([[0.5, 0.6], [0.1, 0.9]], 4.0)


@pytest.mark.parametrize("motion", ["imm-cv-ct", "imm-cv-singer"])
def test_imm_multi_radar_3d_with_coverage_tracks_every_target(motion):
    """Two radars with overlapping coverage, 3-D plots, clutter: every target gets one
    confirmed track whose position error is within a few σ (σ = 30 m per axis)."""
    rng = np.random.default_rng(21)
    n, side = 6, 20_000.0
    x0 = rng.uniform(6_000, 14_000, (n, 3))
    x0[:, 2] = rng.uniform(3_000, 9_000, n)
    v = np.column_stack([rng.normal(0, 50, (n, 2)), rng.normal(0, 3, n)])
    tr = Tracker(TrackerConfig(tracker="lmits", ndim=3, motion=motion, v_max=400.0))
    sites = {"A": np.zeros(2), "B": np.full(2, side)}
    for k in range(1, 40):
        for name, site in sites.items():
            t = 4 * k * NS + (2 * NS if name == "B" else 0)
            pos = x0 + v * t / NS
            seen = np.linalg.norm(pos[:, :2] - site, axis=1) < 22_000
            det = seen & (rng.random(n) < 0.9)
            z = pos[det] + rng.normal(0, 30, (int(det.sum()), 3))
            c = rng.uniform(0, side, (rng.poisson(20), 3))
            cov = SectorCoverage(site, 0.0, 22_000.0, 0.0, 2 * np.pi, 0, 0)
            b = MeasurementBatch(t, name, np.concatenate([z, c]), 900.0 * np.eye(3), 0.9,
                                 20 / side**3, coverage=cov)  # fmt: skip
            out = tr.step(b)
    pos = x0 + v * t / NS
    seen = np.zeros(n, bool)
    for site in sites.values():
        seen |= np.linalg.norm(pos[:, :2] - site, axis=1) < 20_000
    assert seen.sum() >= 5
    est = out.states[out.confirmed][:, 0::2]
    d = np.linalg.norm(est[:, None, :] - pos[None], axis=2)
    assert (d.min(axis=0)[seen] < 150.0).all(), d.min(axis=0)
    assert out.confirmed.sum() <= n + 1
