"""Tracker framework: existence life cycle, initiation, coverage, multi-radar, gating,
Markov chains, duplicates and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.association.gating import gate, window_pairs
from skyfuse.fusion.tracker import MeasurementBatch, SectorCoverage, Tracker, TrackerConfig
from skyfuse.fusion.tracker.existence import markov_chain_one, markov_chain_two

R = 25.0 * np.eye(2)
NS = 10**9


def cfg(**kw):
    base = dict(q=0.75, v_max=50.0, init_max_dt=1.5, clutter="known", psi_init=0.02, motion="cv")
    base.update(kw)
    return TrackerConfig(**base)


@pytest.mark.parametrize("kind", ["ipda", "lmits", "jits", "gnn"])
def test_existence_on_pure_clutter_decays_below_tau_t(kind):
    rng = np.random.default_rng(11)
    c = cfg(tracker=kind, initiation="none", tau_terminate=1e-3)
    tr = Tracker(c)
    tid = tr.add_track([500, 0, 500, 0], np.diag([100.0, 100, 100, 100]), 0, existence=0.5)
    history = []
    for k in range(1, 60):
        z = rng.uniform(0, 1000, (rng.poisson(100), 2))  # ρ = 1e-4 /m²
        out = tr.step(MeasurementBatch(k * NS, "r", z, R, 0.9, 1e-4))
        if tid not in out.ids:
            break
        history.append(out.existence[list(out.ids).index(tid)])
    assert tid not in out.ids, "a clutter-only track must be terminated"
    assert not any(e.kind == "confirmed" for e in out.events)
    assert max(history) < c.tau_confirm


@pytest.mark.parametrize(
    ("kind", "chain"),
    [
        ("ipda", "mc1"),
        ("its", "mc1"),
        ("lmits", "mc1"),
        ("jits", "mc1"),
        ("gnn", "mc1"),
        ("lmits", "mc2"),
    ],
)
def test_detected_target_is_initiated_and_confirmed(kind, chain):
    rng = np.random.default_rng(12)
    c = cfg(tracker=kind, depth=2, existence_chain=chain)
    tr = Tracker(c)
    x = np.array([100.0, 16.0, 100.0, 4.0])  # the thesis STT target ([thesis] §7.3)
    confirmed_at = None
    for k in range(1, 30):
        x = x + np.array([x[1], 0, x[3], 0])
        z = rng.uniform(0, 1000, (rng.poisson(20), 2))  # ρ = 2e-5
        if rng.random() < 0.9:
            z = np.vstack([z, x[[0, 2]] + rng.normal(0, 5, 2)])
        out = tr.step(MeasurementBatch(k * NS, "r", z, R, 0.9, 2e-5))
        if confirmed_at is None and out.confirmed.any():
            confirmed_at = k
    assert confirmed_at is not None and confirmed_at < 12
    conf = np.flatnonzero(out.confirmed)
    err = np.linalg.norm(out.states[conf][:, [0, 2]] - x[[0, 2]], axis=1)
    assert err.min() < 15.0
    assert out.existence[conf[err.argmin()]] > c.tau_confirm


def test_two_point_initiation_state_and_covariance():
    tr = Tracker(cfg(tracker="ipda", init_min_dt=0.5, init_max_dt=5.0))
    tr.step(MeasurementBatch(NS, "r", np.array([[100.0, 200.0]]), R, 0.9, 1e-6))
    out = tr.step(MeasurementBatch(3 * NS, "r", np.array([[140.0, 190.0]]), R, 0.9, 1e-6))
    assert len(out) == 1 and out.stats["initiated"] == 1
    T, r = 2.0, 25.0
    np.testing.assert_allclose(out.states[0], [140.0, 20.0, 190.0, -5.0])
    block = np.array([[r, r / T], [r / T, 2 * r / T**2]])  # (3.25-3.27)
    np.testing.assert_allclose(out.covariances[0][:2, :2], block)
    np.testing.assert_allclose(out.covariances[0][2:, 2:], block)
    assert out.existence[0] == pytest.approx(0.02)


def test_pairs_beyond_v_max_do_not_initiate_and_one_point_does():
    tr = Tracker(cfg(tracker="ipda"))
    tr.step(MeasurementBatch(NS, "r", np.array([[0.0, 0.0]]), R, 0.9, 1e-6))
    out = tr.step(MeasurementBatch(2 * NS, "r", np.array([[80.0, 0.0]]), R, 0.9, 1e-6))
    assert len(out) == 0  # 80 m in 1 s > v_max = 50 m/s
    tr1 = Tracker(cfg(tracker="ipda", initiation="one_point"))
    out = tr1.step(MeasurementBatch(NS, "r", np.array([[5.0, 7.0]]), R, 0.9, 1e-6))
    np.testing.assert_allclose(out.states[0], [5, 0, 7, 0])
    assert out.covariances[0][1, 1] == pytest.approx(50.0**2 / 3)


def test_plots_selected_by_tracks_do_not_initiate():
    tr = Tracker(cfg(tracker="ipda"))
    tr.add_track([0, 10, 0, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.9)
    for k in (1, 2, 3):
        out = tr.step(MeasurementBatch(k * NS, "r", np.array([[10.0 * k, 0.0]]), R, 0.9, 1e-6))
    assert len(out) == 1 and tr.totals["initiated"] == 0


def test_radar_that_does_not_cover_a_track_leaves_it_alone():
    tr = Tracker(cfg(tracker="lmits", depth=2, initiation="none"))
    tid = tr.add_track([10_000, 0, 0, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.8)
    # sector north-east of a radar at the origin: azimuth 0..90° sees y > 0, x > 0 only
    cov = SectorCoverage(np.zeros(2), 0.0, 50_000.0, 0.0, np.pi / 2 - 0.3, 0, NS)
    # the track is due east (azimuth 90°), outside the sector [0°, 73°]
    out = tr.step(MeasurementBatch(NS, "A", np.zeros((0, 2)), R, 0.9, 1e-8, coverage=cov))
    assert out.stats["tracks_in_coverage"] == 0
    assert out.existence[list(out.ids).index(tid)] == pytest.approx(0.98 * 0.8)  # Δ11 only
    # out of range of radar B: also untouched; in coverage of C: a miss lowers ψ
    covB = SectorCoverage(np.array([100_000.0, 0]), 0.0, 50_000.0, 0.0, 2 * np.pi, 0, 0)
    out = tr.step(MeasurementBatch(2 * NS, "B", np.zeros((0, 2)), R, 0.9, 1e-8, coverage=covB))
    assert out.existence[0] == pytest.approx(0.98**2 * 0.8)
    covC = SectorCoverage(np.array([0.0, 0]), 0.0, 50_000.0, 0.0, 2 * np.pi, 0, 0)
    out = tr.step(MeasurementBatch(3 * NS, "C", np.zeros((0, 2)), R, 0.9, 1e-8, coverage=covC))
    assert out.existence[0] < 0.98**3 * 0.8 * 0.5


def test_sector_illumination_time_is_linear_in_azimuth():
    cov = SectorCoverage(np.zeros(2), 0.0, 1e5, np.pi / 2, np.pi / 2, 10 * NS, 12 * NS)
    pos = np.array([[1000.0, 0.0], [1000.0, -1000.0], [0.0, -1000.0], [-5.0, 1000.0]])
    t = cov.illumination_time(pos)
    assert list(t) == [10 * NS, 11 * NS, 12 * NS, 10 * NS]
    assert list(cov.contains(pos)) == [True, True, True, False]


def test_multi_radar_batches_update_one_track_with_per_radar_pd():
    rng = np.random.default_rng(4)
    tr = Tracker(cfg(tracker="lmits", depth=2, initiation="none"))
    tid = tr.add_track([0, 10, 0, 5], np.diag([25.0, 25, 25, 25]), 0, existence=0.5)
    x = np.array([0.0, 10, 0, 5])
    t = 0.0
    for k in range(12):
        radar, dt, pd = ("A", 0.7, 0.9) if k % 2 else ("B", 0.4, 0.6)
        t += dt
        xt = x + t * np.array([10.0, 0, 5, 0])
        Rk = np.diag([16.0, 36.0]) if radar == "A" else np.diag([49.0, 9.0])
        z = (xt[[0, 2]] + rng.multivariate_normal([0, 0], Rk))[None]
        out = tr.step(MeasurementBatch(int(t * NS), radar, z, Rk, pd, 1e-6))
    i = list(out.ids).index(tid)
    assert out.radars_of(i) == ["B", "A"]
    assert out.updates[i] == 12
    assert np.linalg.norm(out.states[i][[0, 2]] - xt[[0, 2]]) < 15


def test_window_pairs_and_gate_match_brute_force():
    rng = np.random.default_rng(0)
    c = rng.uniform(0, 1000, (40, 2))
    p = rng.uniform(0, 1000, (300, 2))
    r = rng.uniform(5, 80, 40)
    i, j = window_pairs(c, r, p)
    box = (np.abs(p[None] - c[:, None]) <= r[:, None, None]).all(axis=2)
    assert set(zip(i.tolist(), j.tolist())) == set(zip(*np.nonzero(box)))
    HPH = np.stack([np.diag(rng.uniform(100, 900, 2)) for _ in range(40)])
    Rp = np.broadcast_to(25 * np.eye(2), (300, 2, 2))
    gp = gate(c, HPH, p, Rp, 9.21)
    S = HPH[:, None] + Rp[None]
    nu = p[None] - c[:, None]
    d2 = np.einsum("cpi,cpij,cpj->cp", nu, np.linalg.inv(S), nu)
    assert set(zip(gp.state.tolist(), gp.plot.tolist())) == set(zip(*np.nonzero(d2 < 9.21)))


def test_markov_chains_match_matrix_powers():
    mc1 = markov_chain_one(0.98, 0.01, period=2.0)
    psi = np.array([0.3, 0.9])
    out = mc1.existence(mc1.predict(np.column_stack([psi, 0 * psi]), np.array([2.0, 4.0])))
    one = 0.98 * 0.3 + 0.01 * 0.7
    p = 0.98 * 0.9 + 0.01 * 0.1
    assert out == pytest.approx([one, 0.98 * p + 0.01 * (1 - p)])
    mc2 = markov_chain_two(0.98, 0.0, 0.1, 0.4)
    Pi = np.array([[0.98 * 0.9, 0.98 * 0.1, 0.02], [0.98 * 0.4, 0.98 * 0.6, 0.02], [0, 0, 1]])
    s = np.array([[0.5, 0.2]])
    want = np.r_[s[0], 0.3] @ np.linalg.matrix_power(Pi, 3)
    np.testing.assert_allclose(mc2.predict(s, np.array([3.0]))[0], want[:2])
    half = mc2.predict(mc2.predict(s, np.array([1.5])), np.array([1.5]))
    np.testing.assert_allclose(half, mc2.predict(s, np.array([3.0])))
    # MC2 update: p_obs ← (1−δ)p_obs, p_unobs kept, normalised by 1 − δ p_obs
    delta = 0.6
    post = (1 - delta) * 0.5 / (1 - delta * 0.5)
    up = mc2.update(s, np.array([post]))
    np.testing.assert_allclose(up[0], [post, 0.2 / (1 - delta * 0.5)])


def test_duplicate_tracks_are_merged_keeping_the_confirmed_one():
    tr = Tracker(cfg(tracker="ipda", initiation="none"))
    a = tr.add_track([0, 10, 0, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.9, confirmed=True)
    tr.add_track([2, 10, 1, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.95)
    out = tr.step(MeasurementBatch(NS, "r", np.array([[10.0, 0.0]]), R, 0.9, 1e-6))
    assert list(out.ids) == [a]
    assert out.stats["duplicates_removed"] == 1
    # two targets 60 m apart in formation, each with its own plot, are not merged
    tr2 = Tracker(cfg(tracker="ipda", initiation="none"))
    tr2.add_track([0, 10, 0, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.9)
    tr2.add_track([0, 10, 60, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.9)
    out = tr2.step(MeasurementBatch(NS, "r", np.array([[10.0, 0.0], [10, 60]]), R, 0.9, 1e-6))
    assert len(out) == 2


def test_confirmed_track_termination_is_an_event():
    tr = Tracker(cfg(tracker="ipda", initiation="none"))
    tid = tr.add_track(
        [0, 10, 0, 0], np.diag([25.0, 25, 25, 25]), 0, existence=0.96, confirmed=True
    )
    for k in range(1, 20):
        out = tr.step(MeasurementBatch(k * NS, "r", np.zeros((0, 2)), R, 0.9, 1e-6))
        if tid not in out.ids:
            break
    assert [e.kind for e in out.events] == ["terminated"] and out.events[0].track_id == tid


def test_bad_plots_are_counted_not_fatal():
    tr = Tracker(cfg(tracker="lmits"))
    z = np.array([[0.0, 1.0], [np.nan, 2.0], [3.0, 4.0]])
    Rb = np.stack([R, R, np.array([[25.0, 0], [0, -1.0]])])
    out = tr.step(MeasurementBatch(NS, "r", z, Rb, 0.9, 1e-6))
    assert out.batch.rejected == {"position not finite": 1, "covariance not positive definite": 1}
    assert len(out.batch) == 1
    with pytest.raises(ValueError, match="p_detection"):
        tr.step(MeasurementBatch(NS, "r", z, R, 1.5, 1e-6))


def test_estimated_clutter_mode_runs_from_empty_and_matches_formula():
    """Non-parametric clutter (2.35): ρ̂ = (m − P_D P_G ψ)/V with V = π g √det S."""
    c = cfg(tracker="ipda", clutter="estimated", initiation="none")
    tr = Tracker(c)
    out = tr.step(MeasurementBatch(NS, "r", np.array([[0.0, 0.0]]), R, 0.9, 0.0))
    assert len(out) == 0
    P0 = np.diag([25.0, 4.0, 25.0, 4.0])
    tid = tr.add_track([0, 0, 0, 0], P0, NS, existence=0.5)
    z = np.array([[3.0, -2.0], [-6.0, 4.0]])
    out = tr.step(MeasurementBatch(2 * NS, "r", z, R, 0.9, 0.0))
    F = np.kron(np.eye(2), [[1.0, 1.0], [0.0, 1.0]])
    Q = np.kron(np.eye(2), 0.75 * np.array([[0.25, 0.5], [0.5, 1.0]]))
    Pp = F @ P0 @ F.T + Q
    S = Pp[np.ix_([0, 2], [0, 2])] + R
    g = -2 * np.log(0.01)
    pdpg = 0.9 * 0.99
    psi_p = 0.98 * 0.5
    V = np.pi * g * np.sqrt(np.linalg.det(S))
    rho = (2 - pdpg * psi_p) / V
    Si = np.linalg.inv(S)
    p = [np.exp(-0.5 * v @ Si @ v) / (2 * np.pi * np.sqrt(np.linalg.det(S))) / 0.99 for v in z]
    lam = 1 - pdpg + pdpg * sum(pi / rho for pi in p)
    want = lam * psi_p / (1 - (1 - lam) * psi_p)
    assert out.existence[list(out.ids).index(tid)] == pytest.approx(want, rel=1e-9)


def test_gnn_picks_the_best_one_to_one_assignment():
    """Two tracks, two plots in both gates: GNN gives each track its own plot (the
    brute-force best of the feasible assignments by likelihood), β = 1 on it."""
    tr = Tracker(cfg(tracker="gnn", initiation="none"))
    P = np.diag([100.0, 25, 100, 25])
    a = tr.add_track([0, 10, 0, 0], P, 0, existence=0.9)
    b = tr.add_track([0, 10, 20, 0], P, 0, existence=0.9)
    z = np.array([[10.0, 17.0], [10.0, 2.0]])  # near b's and a's predictions
    out = tr.step(MeasurementBatch(NS, "r", z, R, 0.9, 1e-6))
    ia, ib = list(out.ids).index(a), list(out.ids).index(b)
    assert out.assigned_plot[ia] == 1 and out.assigned_plot[ib] == 0
    Pyy = 100 + 25 + 0.75 / 4  # predicted y variance; K = Pyy / (Pyy + 25)
    assert out.states[ia][2] == pytest.approx(2.0 * Pyy / (Pyy + 25), rel=1e-9)
    assert out.updates[ia] == out.updates[ib] == 1


def test_three_dimensional_tracking_estimates_climb():
    rng = np.random.default_rng(21)
    tr = Tracker(cfg(tracker="lmits", depth=2, ndim=3, q=1.0, v_max=300.0, init_max_dt=5.0))
    R3 = np.diag([400.0, 400.0, 900.0])
    x = np.array([0.0, 200.0, 0.0, 50.0, 3000.0, 10.0])
    for k in range(1, 16):
        x = x + 4.0 * np.array([x[1], 0, x[3], 0, x[5], 0])
        z = (x[[0, 2, 4]] + rng.multivariate_normal(np.zeros(3), R3))[None]
        out = tr.step(MeasurementBatch(4 * k * NS, "r", z, R3, 0.95, 1e-14))
    assert out.states.shape[1] == 6 and out.confirmed.sum() == 1
    est = out.states[out.confirmed][0]
    assert abs(est[4] - x[4]) < 60 and abs(est[5] - 10.0) < 5 and abs(est[1] - 200) < 10


@pytest.mark.parametrize("max_coast", [120.0, None])
def test_track_outside_every_coverage_ends_after_max_coast(max_coast):
    """No radar sees the track, so misses never erode its existence (Δ11 alone keeps it
    above τ_t for minutes): ``max_coast`` ends it, with a reason on the event."""
    tr = Tracker(cfg(tracker="lmits", depth=2, initiation="none", max_coast=max_coast))
    tid = tr.add_track([200_000, 0, 0, 0], np.diag([25.0] * 4), 0, existence=0.99,
                       confirmed=True)  # fmt: skip
    cov = SectorCoverage(np.zeros(2), 0.0, 50_000.0, 0.0, 2 * np.pi, 0, 0)  # 150 km short
    ended_at, reasons = None, []
    for k in range(1, 21):
        out = tr.step(MeasurementBatch(10 * k * NS, "A", np.zeros((0, 2)), R, 0.9, 1e-8,
                                       coverage=cov))  # fmt: skip
        reasons += [e.reason for e in out.events if e.kind == "terminated"]
        if tid not in out.ids:
            ended_at = 10 * k
            break
    if max_coast is None:
        assert ended_at is None and out.existence[0] > 1e-3
    else:
        assert ended_at == 130  # first batch more than 120 s after the last update (t = 0)
        assert reasons == ["no plot for max_coast"]
