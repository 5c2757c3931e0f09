"""IPDA against numbers worked in the test from the thesis's equations ([thesis] §2.3.1).

The reference below is written from the equations directly (KF 2.21-2.27, p = N/P_G
(2.40), Λ (5.16), ψ (2.41), β (2.38), the combined mean/covariance (2.37 corrected)) with
plain 2×2 / 4×4 algebra; it shares no code with ``fusion.tracker``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from skyfuse.fusion.tracker import MeasurementBatch, Tracker, TrackerConfig

T = 1.0
Q_ACC = 0.75
R = 25.0 * np.eye(2)
D11 = 0.98
PD = 0.9
RHO = 1e-4
F = np.array([[1, T, 0, 0], [0, 1, 0, 0], [0, 0, 1, T], [0, 0, 0, 1]], float)
QT = Q_ACC * np.array([[T**4 / 4, T**3 / 2], [T**3 / 2, T**2]])
Q = np.zeros((4, 4))
Q[:2, :2] = QT
Q[2:, 2:] = QT
H = np.array([[1, 0, 0, 0], [0, 0, 1, 0]], float)
G = -2.0 * math.log(1 - 0.99)  # 2-D chi-square quantile of P_G = 0.99: g = 9.21
PG = 1 - math.exp(-G / 2)


def ipda_reference(x, P, psi, plots):
    """One IPDA scan, written from [thesis] §2.3.1 with explicit formulas."""
    xp = F @ x
    Pp = F @ P @ F.T + Q
    psi_p = D11 * psi  # (3.40), Δ21 = 0
    S = H @ Pp @ H.T + R
    detS = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    Sinv = np.array([[S[1, 1], -S[0, 1]], [-S[1, 0], S[0, 0]]]) / detS
    K = Pp @ H.T @ Sinv
    gated, lik = [], []
    for z in plots:
        nu = z - H @ xp
        d2 = nu @ Sinv @ nu
        if d2 < G:
            gated.append(z)
            lik.append(math.exp(-0.5 * d2) / (2 * math.pi * math.sqrt(detS)) / PG)  # (2.40)
    lam = 1 - PD * PG + PD * PG * sum(p / RHO for p in lik)  # (5.16)
    psi_u = lam * psi_p / (1 - (1 - lam) * psi_p)  # (2.41)
    betas = [(1 - PD * PG) / lam] + [PD * PG * p / RHO / lam for p in lik]  # (2.38)
    xs, Ps = [xp], [Pp]
    A = np.eye(4) - K @ H
    for z in gated:
        xs.append(xp + K @ (z - H @ xp))
        Ps.append(A @ Pp @ A.T + K @ R @ K.T)  # Joseph (5.14)
    xm = sum(b * xi for b, xi in zip(betas, xs))
    Pm = sum(b * (Pi + np.outer(xi - xm, xi - xm)) for b, xi, Pi in zip(betas, xs, Ps))
    return xm, Pm, psi_u, len(gated)


def make_tracker(kind="ipda", depth=0, **kw):
    cfg = TrackerConfig(
        motion="cv",
        tracker=kind,
        depth=depth,
        q=Q_ACC,
        delta11=D11,
        delta21=0.0,
        p_gate=0.99,
        initiation="none",
        prune_threshold=0.0,
        max_components=10_000,
        clutter="known",
        **kw,
    )
    return Tracker(cfg)


def batch(k, plots):
    return MeasurementBatch(
        time_ns=k * 10**9,
        radar_id="r1",
        z=np.asarray(plots, float).reshape(-1, 2),
        R=R,
        p_detection=PD,
        clutter_density=RHO,
    )


X0 = np.array([0.0, 10.0, 0.0, 5.0])
P0 = np.zeros((4, 4))
P0[:2, :2] = P0[2:, 2:] = [[25.0, 25.0], [25.0, 50.0]]  # two-point P_{2|2}, r = 25, T = 1


def test_two_scan_ipda_matches_hand_worked_equations():
    tr = make_tracker()
    tid = tr.add_track(X0, P0, 0, existence=0.5)
    scans = [
        [[12.0, 3.0], [6.0, 9.0], [500.0, 500.0]],  # two in the gate, one far away
        [[19.0, 11.5]],
    ]
    x, P, psi = X0, P0, 0.5
    for k, plots in enumerate(scans, start=1):
        x, P, psi, n_gated = ipda_reference(x, P, psi, np.asarray(plots))
        out = tr.step(batch(k, plots))
        i = list(out.ids).index(tid)
        assert out.existence[i] == pytest.approx(psi, rel=1e-9)
        np.testing.assert_allclose(out.states[i], x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(out.covariances[i], P, rtol=1e-8, atol=1e-8)
    assert n_gated == 1
    # hand check of the first scan's existence direction: two close plots raise ψ
    assert psi > 0.5


def test_missed_scan_lowers_existence_by_closed_form():
    tr = make_tracker()
    tid = tr.add_track(X0, P0, 0, existence=0.5)
    out = tr.step(batch(1, np.zeros((0, 2))))
    psi_p = D11 * 0.5
    lam = 1 - PD * PG
    expected = lam * psi_p / (1 - (1 - lam) * psi_p)
    i = list(out.ids).index(tid)
    assert out.existence[i] == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(out.states[i], F @ X0, atol=1e-12)


@pytest.mark.parametrize("kind", ["its", "jits", "lmits"])
def test_its_depth_zero_is_ipda_over_cluttered_scans(kind):
    """ITS with N = 0 (and its multi-target variants with a single track) ≡ IPDA."""
    rng = np.random.default_rng(7)
    tr = make_tracker(kind, depth=0)
    tid = tr.add_track(X0, P0, 0, existence=0.3)
    x, P, psi = X0, P0, 0.3
    truth = X0.copy()
    for k in range(1, 13):
        truth = F @ truth
        plots = list(rng.uniform(-60, 60, (rng.poisson(4), 2)) + H @ truth)
        if rng.random() < PD:
            plots.append(H @ truth + rng.normal(0, 5, 2))
        plots = np.asarray(plots).reshape(-1, 2)
        x, P, psi, _ = ipda_reference(x, P, psi, plots)
        out = tr.step(batch(k, plots))
        i = list(out.ids).index(tid)
        assert out.existence[i] == pytest.approx(psi, rel=1e-8)
        np.testing.assert_allclose(out.states[i], x, rtol=1e-8, atol=1e-7)
        np.testing.assert_allclose(out.covariances[i], P, rtol=1e-7, atol=1e-7)


def test_ipda_and_its0_configs_agree():
    rng = np.random.default_rng(3)
    a, b = make_tracker("ipda"), make_tracker("its", depth=0)
    a.add_track(X0, P0, 0, existence=0.3)
    b.add_track(X0, P0, 0, existence=0.3)
    truth = X0.copy()
    for k in range(1, 8):
        truth = F @ truth
        plots = np.vstack([rng.uniform(-40, 40, (3, 2)) + H @ truth, H @ truth])
        oa, ob = a.step(batch(k, plots)), b.step(batch(k, plots))
        np.testing.assert_allclose(oa.states, ob.states)
        np.testing.assert_allclose(oa.existence, ob.existence)
