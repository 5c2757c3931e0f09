"""The motions of the source's filters ([MZD]: ``singer``, ``imm-pcwpa``; [Dikić]:
``imm-cv-singer-ct``) and the IMM density behind them, one track at a time, against an
independent textbook IMM written here with explicit loops (mixing eq. 15-17, Kalman
filters from the models' F and Q, likelihoods and mode probabilities eq. 18-19, output
eq. 20-21) on a target that turns at 4 g."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.fusion.tracker.density.source_motions import G0, PCWPA_SIGMAS, SOURCE_TPM_IMM2
from skyfuse.fusion.tracker.registry import make_density
from skyfuse.fusion.tracker.store import NewTracks, store_for

T = 4.0


def _embed(model, x, P, accel_var):
    """Mode ``model``'s initial state from the CV-layout x (4,), P (4, 4): CV as it is;
    Singer [x, vx, ax, y, vy, ay] with zero accelerations of variance ``accel_var``."""
    return (x.copy(), P.copy()) if model.dim == 4 else _singer_of_cv(x, P, accel_var)


def _singer_of_cv(x, P, accel_var):
    idx = [0, 1, 3, 4]
    xs, Ps = np.zeros(6), np.zeros((6, 6))
    xs[idx] = x
    Ps[np.ix_(idx, idx)] = P
    Ps[2, 2] = Ps[5, 5] = accel_var
    return xs, Ps


def _to_singer(model, x, P):
    """A mode's state in the Singer layout (CV: zero acceleration of zero variance)."""
    return (x, P) if model.dim == 6 else _singer_of_cv(x, P, 0.0)


def _from_singer(model, x, P):
    """A Singer-layout state in ``model``'s layout (CV: the accelerations dropped)."""
    return (x, P) if model.dim == 6 else _cv_part(x, P)


def _cv_part(x, P):
    """The CV-layout entries [x, vx, y, vy] of a CV (as it is) or Singer state."""
    if len(x) == 4:
        return x, P
    idx = [0, 1, 3, 4]
    return x[idx], P[np.ix_(idx, idx)]


def _reference_imm(models, tpm, mu, xs, Ps, zs, R):
    """Textbook IMM of one track over the plots ``zs`` (one per scan of T s); returns the
    CV-layout output and the mode probabilities after every scan."""
    r = len(models)
    same = len({m.dim for m in models}) == 1
    conv = (lambda m, x, P: (x, P)) if same else _to_singer
    back = (lambda m, x, P: (x, P)) if same else _from_singer
    out = []
    for z in zs:
        c = np.array([sum(tpm[i][j] * mu[i] for i in range(r)) for j in range(r)])
        common = [conv(m, xs[i], Ps[i]) for i, m in enumerate(models)]
        like = np.zeros(r)
        for j, m in enumerate(models):
            w = [tpm[i][j] * mu[i] / c[j] for i in range(r)]
            x0 = sum(w[i] * common[i][0] for i in range(r))
            P0 = sum(w[i] * (common[i][1] + np.outer(common[i][0] - x0, common[i][0] - x0))
                     for i in range(r))  # fmt: skip
            x0, P0 = back(m, x0, P0)
            F, Q, H = m.F(T), m.Q(T), m.H()
            x1, P1 = F @ x0, F @ P0 @ F.T + Q
            S = H @ P1 @ H.T + R
            nu = z - H @ x1
            K = P1 @ H.T @ np.linalg.inv(S)
            xs[j], Ps[j] = x1 + K @ nu, (np.eye(m.dim) - K @ H) @ P1
            like[j] = np.exp(-0.5 * nu @ np.linalg.solve(S, nu)) / (
                2 * np.pi * np.sqrt(np.linalg.det(S))
            )
        mu = c * like / (c * like).sum()
        cv = [_cv_part(xs[j], Ps[j]) for j in range(r)]
        x = sum(mu[j] * cv[j][0] for j in range(r))
        P = sum(mu[j] * (cv[j][1] + np.outer(cv[j][0] - x, cv[j][0] - x)) for j in range(r))
        out.append((x, P, mu.copy()))
    return out


def _turn_plots(rng, n=14, sigma=60.0):
    pos, vel = np.array([20_000.0, 5_000.0]), np.array([-250.0, 90.0])
    zs = []
    for k in range(n):
        for _ in range(400):
            if 5 <= k < 8:
                vel = vel + 4 * G0 * np.array([-vel[1], vel[0]]) / np.linalg.norm(vel) * 0.01
            pos = pos + vel * 0.01
        zs.append(pos + rng.normal(0, sigma, 2))
    return zs, np.eye(2) * sigma**2


@pytest.mark.parametrize(
    "motion,settings",
    [
        ("imm-pcwpa", {"imm_tpm": list(SOURCE_TPM_IMM2), "imm_mu0": [0.5, 0.5]}),
        ("imm-pcwpa", {"imm_tpm": [0.95, 0.05, 0.1, 0.9], "imm_mu0": [0.9, 0.1]}),
        ("imm-cv-singer", {"imm_singer_sigma_m": 49.0, "imm_mu0": [0.8, 0.2]}),
        ("singer", {"imm_singer_tau": 10.0, "imm_singer_sigma_m": 49.0}),
    ],
)
def test_one_track_of_the_density_equals_a_textbook_imm(motion, settings):
    cfg = TrackerConfig(
        tracker="gnn", motion=motion, imm_tpm_period=T, reach_gate=False, imm_coast_after=None,
        imm_init_acceleration=10.0, **settings,
    )  # fmt: skip
    density = make_density(cfg)
    models = density.models
    if motion == "imm-pcwpa":
        assert [m.q for m in models] == pytest.approx([s**2 for s in PCWPA_SIGMAS])
    tpm = np.reshape(cfg.imm_tpm, (2, 2)) if len(models) == 2 else np.eye(1)
    mu0 = np.asarray(cfg.imm_mu0 if len(models) == 2 else [1.0], float)
    rng = np.random.default_rng(3)
    zs, R = _turn_plots(rng)
    x0 = np.array([zs[0][0], -250.0, zs[0][1], 90.0])
    P0 = np.diag([R[0, 0], 100.0**2, R[1, 1], 100.0**2])
    store_for(density).append(NewTracks(x0[None], P0[None]))
    start = [_embed(m, x0, P0, 10.0**2) for m in models]
    ref = _reference_imm(
        models, tpm, mu0 / mu0.sum(), [a for a, _ in start], [b for _, b in start], zs[1:], R
    )
    rows = np.array([0])
    for z, (x, P, mu) in zip(zs[1:], ref):
        pred = density.predict(rows, np.array([T]))
        table = density.likelihoods(pred, z[None], R[None], 1e4)
        assert len(table) == 1
        density.update(pred, table, np.zeros(1), np.ones(1))
        xd, Pd = density.estimate(rows)
        np.testing.assert_allclose(xd[0], x, rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(Pd[0], P, rtol=1e-8, atol=1e-6)
        np.testing.assert_allclose(density.mode_probabilities(rows)[0], mu, rtol=1e-8, atol=1e-12)


def test_the_three_model_motion_needs_three_modes_and_runs_with_them():
    with pytest.raises(ValueError, match="3 modes"):
        make_density(TrackerConfig(motion="imm-cv-singer-ct"))
    cfg = TrackerConfig(
        motion="imm-cv-singer-ct", imm_tpm=[0.9, 0.05, 0.05, 0.05, 0.9, 0.05, 0.05, 0.05, 0.9],
        imm_mu0=[1.0, 1.0, 1.0],
    )  # fmt: skip
    d = make_density(cfg)
    assert [type(m).__name__ for m in d.models] == ["ConstantVelocity", "Singer", "CoordinatedTurn"]


IMM3 = {
    "imm_q_cv": (G0 / 2) ** 2, "imm_singer_tau": 10.0, "imm_singer_sigma_m": 2 * G0,
    "imm_ct_sigma_a": 2.0, "imm_ct_sigma_omega": 0.02,
    "imm_tpm": [0.9, 0.05, 0.05, 0.05, 0.9, 0.05, 0.05, 0.05, 0.9],
}  # fmt: skip
"""[Dikić]'s three-model IMM with the parameters of the crossing-4g baseline."""


def _density(motion, **settings):
    cfg = TrackerConfig(
        tracker="gnn", motion=motion, imm_tpm_period=T, reach_gate=False, imm_coast_after=None,
        imm_init_acceleration=10.0, **settings,
    )  # fmt: skip
    return make_density(cfg)


def _own_plots(density, z, R, start):
    """n tracks, each updated with its own plot z[i, k] (n, steps, m) of every scan k ≥
    ``start``; returns the mean mode probabilities after each scan."""
    n = z.shape[0]
    rows = np.arange(n)
    mus = []
    for k in range(start, z.shape[1]):
        pred = density.predict(rows, np.full(n, T))
        table = density.likelihoods(pred, z[:, k], np.broadcast_to(R, (n, *R.shape)), 1e4)
        own = table.tp_plot == pred.rows[table.tp_track]
        assert own.sum() == n
        density.update(pred, table, np.zeros(n), own.astype(float))
        for P in density.comp.P:
            assert np.isfinite(P).all()
        mus.append(density.mode_probabilities(rows).mean(axis=0))
    return np.array(mus)


def _turning_truth(n_runs, rng, steps=20, turn=(8, 11)):
    """Straight flight at 300 m/s, then a 4 g turn between scans turn[0] and turn[1]."""
    pos, v = np.array([0.0, 0.0]), np.array([300.0, 0.0])
    out = []
    for k in range(steps):
        for _ in range(400):
            if turn[0] <= k < turn[1]:
                v = v + 4 * G0 * np.array([-v[1], v[0]]) / np.linalg.norm(v) * 0.01
            pos = pos + v * 0.01
        out.append(pos.copy())
    truth = np.array(out)
    return truth, truth[None] + rng.normal(0, 50.0, (n_runs, steps, 2)), np.eye(2) * 50.0**2


@pytest.mark.parametrize(
    "motion,settings",
    [
        ("imm-pcwpa", {"imm_tpm": [0.95, 0.05, 0.1, 0.9], "imm_mu0": [0.9, 0.1]}),
        ("imm-cv-singer-ct", IMM3 | {"imm_mu0": [0.9, 0.05, 0.05]}),
    ],
)
def test_the_manoeuvre_modes_take_over_during_a_4g_turn(motion, settings):
    from skyfuse.fusion.filters.initiation import two_point

    density = _density(motion, **settings)
    n = 100
    truth, z, R = _turning_truth(n, np.random.default_rng(6))
    store_for(density).append(NewTracks(*two_point(z[:, 0], R, z[:, 1], R, T)))
    mus = _own_plots(density, z, R, 2)  # index k − 2
    cv_before = mus[4 - 2 : 6 - 2, 0].mean()  # scans 4-5
    cv_during = mus[9 - 2 : 11 - 2, 0].mean()  # scans 9-10
    assert cv_before > 0.6
    assert cv_during < cv_before - 0.3
    x, _ = density.estimate(np.arange(n))
    err = np.linalg.norm(x[:, [0, 2]] - truth[-1], axis=1)
    assert np.sqrt((err**2).mean()) < 200


def test_the_three_model_imm_from_a_one_point_start_converges_without_blowing_up():
    """Zero initial velocity leaves the turn mode's course undefined: the conversion falls
    back to an uninformative course instead of exploding (1e7 m errors once)."""
    from skyfuse.fusion.filters.initiation import one_point

    density = _density("imm-cv-singer-ct", **IMM3, imm_mu0=[1.0, 1.0, 1.0])
    rng = np.random.default_rng(11)
    n = 50
    R = np.eye(2) * 100.0**2
    truth = np.array([30_000.0, 30_000.0]) + np.arange(10)[:, None] * T * np.array([-220.0] * 2)
    z = truth[None] + rng.normal(0, 100.0, (n, 10, 2))
    store_for(density).append(NewTracks(*one_point(z[:, 0], R, 350.0**2)))
    _own_plots(density, z, R, 1)
    x, _ = density.estimate(np.arange(n))
    err = np.linalg.norm(x[:, [0, 2]] - truth[-1], axis=1)
    assert np.sqrt((err**2).mean()) < 150


def test_the_three_model_imm_with_the_altitude_channel_tracks_a_climbing_target():
    from skyfuse.fusion.filters.initiation import two_point

    density = _density("imm-cv-singer-ct", **IMM3, imm_mu0=[1.0, 1.0, 1.0], ndim=3, q_vertical=1.0)
    assert density.models[0].labels == ("x", "vx", "y", "vy", "z", "vz")
    rng = np.random.default_rng(12)
    n = 40
    R = np.diag([80.0**2, 80.0**2, 30.0**2])
    truth = np.array([10_000.0, 20_000.0, 3000.0]) + np.arange(12)[:, None] * T * np.array(
        [250.0, -100.0, 10.0]
    )
    z = truth[None] + rng.normal(size=(n, 12, 3)) * np.sqrt(np.diag(R))
    store_for(density).append(NewTracks(*two_point(z[:, 0], R, z[:, 1], R, T)))
    _own_plots(density, z, R, 2)
    x, _ = density.estimate(np.arange(n))
    assert x.shape == (n, 6)
    np.testing.assert_allclose(x[:, 5].mean(), 10.0, atol=3.0)  # climb rate
    err = np.linalg.norm(x[:, [0, 2, 4]] - truth[-1], axis=1)
    assert np.sqrt((err**2).mean()) < 100
