"""Planar cartesian sensor of the thesis scenarios: binomial detection, R = σ² I errors
(chi-square), clutter regions of thesis-stt (Poisson counts, uniformity), scan timing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.sim import Simulator, build_scenario


def test_detection_rate_within_binomial_bounds():
    sc = build_scenario("thesis-mtt-15", seed=1)
    hits = trials = 0
    for seed in range(10):
        for s in Simulator(sc, seed=seed).scans():
            tid = s.target_id[s.target_id >= 0]
            assert len(np.unique(tid)) == len(tid)
            hits += len(tid)
            trials += sc.n_targets
    assert trials == 10 * 40 * 15
    lo, hi = stats.binom.ppf([0.0005, 0.9995], trials, 0.8)
    assert lo <= hits <= hi


def test_cartesian_errors_are_gaussian_with_r_25i():
    sc = build_scenario("thesis-mtt-50", seed=2)
    e = []
    for seed in range(3):
        sim = Simulator(sc, seed=seed)
        for s in sim.scans():
            d = sim.truth_at(np.array([s.time_start]), geodetic=False)
            m = s.target_id >= 0
            col = np.searchsorted(d["target_id"], s.target_id[m])
            e.append(np.column_stack([s.x[m] - d["x"][0, col], s.y[m] - d["y"][0, col]]) / 5.0)
    e = np.concatenate(e)
    n = len(e)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    for j in range(2):
        assert lo <= (e[:, j] ** 2).sum() <= hi
        assert abs(e[:, j].mean()) < 3.3 / math.sqrt(n)
    assert abs(np.corrcoef(e.T)[0, 1]) < 3.3 / math.sqrt(n)


def test_thesis_stt_clutter_regions_poisson_and_uniform():
    sc = build_scenario("thesis-stt", seed=1)
    split = sc.params["split_x"]
    assert split * 900 == pytest.approx(3.0e5) and (900 - split) * 900 == pytest.approx(5.1e5)
    weak, strong, xs = [], [], []
    for seed in range(6):
        for s in Simulator(sc, seed=seed).scans():
            c = s.target_id == -1
            x, y = s.x[c], s.y[c]
            assert ((x >= 0) & (x <= 900) & (y >= 0) & (y <= 900)).all()
            weak.append((x < split).sum())
            strong.append((x >= split).sum())
            xs.append(x[x >= split])
    n = len(weak)
    assert n == 6 * 50
    for counts, lam in ((np.array(weak), 6.0), (np.array(strong), 102.0)):
        lo, hi = stats.poisson.ppf([0.0005, 0.9995], n * lam)
        assert lo <= counts.sum() <= hi
        disp = ((counts - lam) ** 2).sum() / lam
        clo, chi = stats.chi2.ppf([0.0005, 0.9995], n)
        assert clo <= disp <= chi
    xs = np.concatenate(xs)
    assert stats.kstest((xs - split) / (900 - split), "uniform").pvalue > 1e-3


def test_scan_numbering_and_times_follow_the_spec():
    sc = build_scenario("thesis-stt", q=0.0)
    sim = Simulator(sc, seed=0)
    scans = list(sim.scans())
    assert [s.scan for s in scans] == list(range(1, 51))
    assert [(s.time_start - sc.start_time) / 1e9 for s in scans] == [float(k) for k in range(1, 51)]
    d = sim.truth_at(np.array([scans[-1].time_start]))
    assert (d["x"][0, 0], d["y"][0, 0]) == pytest.approx((900.0, 300.0))
    batches = [e.message for e in sim.run() if e.kind == "plots"]
    assert len(batches) == 50
    assert all(
        b.sector_width == pytest.approx(2 * math.pi) and b.time_start == b.time_end for b in batches
    )
    for b, s in zip(batches, scans):
        assert b.scan == s.scan and len(b) == len(s)
        np.testing.assert_array_equal(b.column("x"), s.x)


def test_thesis_stt_process_noise_has_the_discrete_white_acceleration_covariance():
    """q = 0.75: position deviation from the straight line after n steps of T = 1 s has
    variance q Σ_k (n − k − 1/2)² T⁴ ... computed by the recursion of F and Q."""
    q, n_steps = 0.75, 10
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    Q = q * np.array([[0.25, 0.5], [0.5, 1.0]])
    P = np.zeros((2, 2))
    for _ in range(n_steps):
        P = F @ P @ F.T + Q
    dev = []
    for seed in range(200):
        sc = build_scenario("thesis-stt", seed=seed, duration=10)
        p, v = sc.targets.state(np.array([float(n_steps)]), np.array([0]))
        dev.append([p[0, 0] - (100 + 16 * n_steps), v[0, 0] - 16.0])
    dev = np.array(dev)
    for j in range(2):
        s2 = (dev[:, j] ** 2).sum() / P[j, j]
        lo, hi = stats.chi2.ppf([0.0005, 0.9995], len(dev))
        assert lo <= s2 <= hi


def test_batched_snapshot_path_equals_the_per_scan_path():
    from skyfuse.fusion.sim.cartesian import cartesian_scan

    sc = build_scenario("thesis-stt", seed=2, clutter_density=1e-5)
    sim = Simulator(sc, seed=7)
    fast = list(sim.scans())
    rng = np.random.default_rng(np.random.SeedSequence(7, spawn_key=(1, 0)))
    cfg = sc.sensors[0]
    slow = [cartesian_scan(cfg, k, sc.targets, rng, sc.start_time) for k in cfg.scans_in(50.0)]
    assert len(fast) == len(slow) == 50
    for a, b in zip(fast, slow):
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.y, b.y)
        np.testing.assert_array_equal(a.target_id, b.target_id)


def test_clutter_density_at_matches_the_density_the_sensor_samples():
    """The density a known-clutter tracker is told (``clutter_density_at``) against the
    clutter actually drawn: Poisson counts per 100 m cell over 400 scans, with a uniform
    coverage density overlapping both thesis-stt regions (densities add)."""
    from skyfuse.fusion.sim.cartesian import clutter_density_at

    sc = build_scenario("thesis-stt", seed=1, clutter_density=1e-5, split_x=300.0)
    cfg = sc.sensors[0]
    edges = np.arange(0.0, 901.0, 100.0)
    counts = np.zeros((9, 9))
    n = 0
    for seed in range(8):
        for s in Simulator(sc, seed=seed).scans():
            c = s.target_id == -1
            counts += np.histogram2d(s.x[c], s.y[c], bins=[edges, edges])[0]
            n += 1
    cx, cy = np.meshgrid(edges[:-1] + 50.0, edges[:-1] + 50.0, indexing="ij")
    rho = clutter_density_at(cfg, cx, cy)
    np.testing.assert_allclose(rho, np.where(cx < 300.0, 3e-5, 2.1e-4), rtol=1e-12)
    lam = rho * 100.0 * 100.0 * n
    lo = stats.poisson.ppf(0.0005 / 81, lam)
    hi = stats.poisson.ppf(1 - 0.0005 / 81, lam)
    assert ((counts >= lo) & (counts <= hi)).all()
    # outside the coverage nothing is drawn and nothing is told; the split edge is counted once
    outside = clutter_density_at(cfg, np.array([-1.0, 950.0]), np.array([10.0, 10.0]))
    assert outside.tolist() == [0.0, 0.0]
    assert clutter_density_at(cfg, np.array([300.0]), np.array([5.0]))[0] == pytest.approx(2.1e-4)
