"""Rotating 2d/3d radar statistics against independent references: binomial detection,
Poisson clutter, chi-square of polar errors against pymap3d geometry, beam-crossing
times against the antenna rotation law, sector batch structure."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from scipy import stats
from skyfuse.fusion.frames import Stereographic
from skyfuse.fusion.sim import Simulator, build_scenario

TWO_PI = 2 * math.pi


def wrap_pi(a):
    return (np.asarray(a) + math.pi) % TWO_PI - math.pi


def concat(scans, name):
    return np.concatenate([getattr(s, name) for s in scans])


def truth_geometry(sim, site, times, tids):
    """Target (lat, lon, alt) at the plot times, then az/el/range with pymap3d."""
    d = sim.truth_at(times)
    col = np.searchsorted(d["target_id"], tids)
    rows = np.arange(len(times))
    lat, lon, alt = d["lat"][rows, col], d["lon"][rows, col], d["alt"][rows, col]
    az, el, r = pymap3d.geodetic2aer(lat, lon, alt, site.lat, site.lon, site.alt)
    return np.radians(az), np.radians(el), r, alt


def test_detection_rate_within_binomial_bounds():
    pd = 0.7
    sc = build_scenario("crossing-4g", p_detection=pd)
    hits = trials = 0
    for seed in range(20):
        scans = list(Simulator(sc, seed=seed).scans())
        for s in scans:
            tid = s.target_id[s.target_id >= 0]
            assert len(np.unique(tid)) == len(tid)  # at most one plot per target and scan
            hits += len(tid)
            trials += 2
    lo, hi = stats.binom.ppf([0.0005, 0.9995], trials, pd)
    assert trials == 20 * 18 * 2
    assert lo <= hits <= hi, (hits, trials, lo, hi)


@pytest.fixture(scope="module")
def clutter_scans():
    sc = build_scenario("crossing-4g", clutter_density=2e-9, p_detection=1.0, n_sectors=8)
    scans = []
    for seed in range(10):
        scans += list(Simulator(sc, seed=seed).scans())
    return sc, scans


def test_clutter_count_poisson_mean_and_dispersion(clutter_scans):
    sc, scans = clutter_scans
    site = sc.sites[0]
    lam = site.clutter_density * math.pi * (site.max_range**2 - site.min_range**2)
    counts = np.array([(s.target_id == -1).sum() for s in scans])
    n = len(counts)
    lo, hi = stats.poisson.ppf([0.0005, 0.9995], n * lam)
    assert lo <= counts.sum() <= hi, (counts.sum(), n * lam)
    disp = ((counts - lam) ** 2).sum() / lam  # ~ chi2(n) for Poisson counts
    clo, chi = stats.chi2.ppf([0.0005, 0.9995], n)
    assert clo <= disp <= chi, (disp, n)
    # per sector: Poisson with a sector's share of the area
    per_sector = np.array([np.bincount(s.sector[s.target_id == -1], minlength=8) for s in scans])
    lo, hi = stats.poisson.ppf([0.0005, 0.9995], n * lam / 8)
    assert ((per_sector.sum(0) >= lo) & (per_sector.sum(0) <= hi)).all()


def test_clutter_is_uniform_in_area_and_azimuth(clutter_scans):
    sc, scans = clutter_scans
    site = sc.sites[0]
    c = concat(scans, "target_id") == -1
    r = concat(scans, "range")[c]
    az = concat(scans, "azimuth")[c]
    assert stats.kstest((r / site.max_range) ** 2, "uniform").pvalue > 1e-3
    assert stats.kstest(az / TWO_PI, "uniform").pvalue > 1e-3
    # a clutter plot's time is when the beam passes its azimuth
    for s in scans[:5]:
        cc = s.target_id == -1
        beam = TWO_PI * (s.time[cc] - s.time_start) / (s.time_end - s.time_start)
        assert np.abs(beam - s.azimuth[cc]).max() < 1e-6


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_plot_errors_chi_square_against_pymap3d(kind):
    """Each normalised error component (range, azimuth, elevation/altitude) is N(0, 1):
    chi-square of its sum of squares and its mean, per component."""
    sc = build_scenario("crossing-4g", radar_kind=kind, sigma_az_mrad=6.0)
    site = sc.sites[0]
    errs = []
    for seed in range(40):
        sim = Simulator(sc, seed=seed)
        scans = list(sim.scans())
        t = concat(scans, "time")
        tid = concat(scans, "target_id")
        az, el, r, alt = truth_geometry(sim, site, t, tid)
        e_r = (concat(scans, "range") - r) / site.sigma_range
        e_a = wrap_pi(concat(scans, "azimuth") - az) / site.sigma_azimuth
        if kind == "3d":
            e_3 = (concat(scans, "elevation") - el) / site.sigma_elevation
        else:
            e_3 = (concat(scans, "altitude") - alt) / site.sigma_altitude
        errs.append(np.column_stack([e_r, e_a, e_3]))
    e = np.concatenate(errs)
    n = len(e)
    assert n == 40 * 18 * 2
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    for j in range(3):
        assert lo <= (e[:, j] ** 2).sum() <= hi, (j, (e[:, j] ** 2).sum(), n)
        assert abs(e[:, j].mean()) < 3.3 / math.sqrt(n)
    assert np.abs(np.corrcoef(e.T) - np.eye(3)).max() < 3.3 / math.sqrt(n)


def test_straight_flight_truth_matches_an_independent_closed_form():
    """crossing-4g before the turn: (R0 − v t)(sin az, cos az) on the plane at (lat0, lon0)."""
    sc = build_scenario("crossing-4g")
    sim = Simulator(sc, seed=0)
    t = np.array([0.0, 10.0, 33.0])
    d = sim.truth_at(sc.start_time + (t * 1e9).astype(np.int64))
    plane = Stereographic(sc.frame.lat0, sc.frame.lon0)
    for j, az_deg in enumerate((45.0, 46.1)):
        a = math.radians(az_deg)
        rr = 50_000.0 - 311.0 * t
        lat, lon = plane.inverse(rr * math.sin(a), rr * math.cos(a))
        np.testing.assert_allclose(d["lat"][:, j], lat, atol=1e-9)
        np.testing.assert_allclose(d["lon"][:, j], lon, atol=1e-9)
        az, _, _ = pymap3d.geodetic2aer(lat, lon, 3000.0, sc.frame.lat0, sc.frame.lon0, 0.0)
        assert np.abs(wrap_pi(np.radians(az) - a)).max() < 2e-3  # small plane distortion


@pytest.fixture(scope="module")
def regional_events():
    sc = build_scenario("regional", duration=40, seed=3, altitude_quantum_ft=0.0)
    sim = Simulator(sc, seed=5)
    return sc, sim, list(sim.run())


def test_beam_crossing_times_follow_the_antenna_rotation(regional_events):
    sc, sim, events = regional_events
    sites = {s.radar_id: s for s in sc.sites}
    checked = 0
    for ev in events:
        if ev.kind != "plots" or len(ev.message) == 0:
            continue
        b = ev.message
        tid = b.column("target_id")
        m = tid >= 0
        if not m.any():
            continue
        t = b.column("time")[m]
        az_true, _, _, _ = truth_geometry(sim, sites[b.radar_id], t, tid[m])
        frac = (t - b.time_start) / (b.time_end - b.time_start)
        beam = b.sector_start + frac * b.sector_width
        assert np.abs(wrap_pi(az_true - beam)).max() < 1e-6
        checked += int(m.sum())
    assert checked > 200


def test_regional_plot_errors_chi_square(regional_events):
    sc, sim, events = regional_events
    sites = {s.radar_id: s for s in sc.sites}
    z2, n = 0.0, 0
    for ev in events:
        if ev.kind != "plots":
            continue
        b = ev.message
        tid = b.column("target_id")
        m = tid >= 0
        if not m.any():
            continue
        site = sites[b.radar_id]
        az, el, r, alt = truth_geometry(sim, site, b.column("time")[m], tid[m])
        e = [(b.column("range")[m] - r) / site.sigma_range,
             wrap_pi(b.column("azimuth")[m] - az) / site.sigma_azimuth]  # fmt: skip
        if site.kind == "3d":
            e.append((b.column("elevation")[m] - el) / site.sigma_elevation)
        else:
            e.append((b.column("altitude")[m] - alt) / site.sigma_altitude)
        e = np.concatenate(e)
        z2 += (e**2).sum()
        n += e.size
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n)
    assert n > 600 and lo <= z2 <= hi, (z2, n)


def test_sector_batches_are_contiguous_and_cover_each_scan(regional_events):
    sc, _, events = regional_events
    times = [e.time for e in events]
    assert times == sorted(times)
    assert [e.kind for e in events[: len(sc.sites)]] == ["site"] * len(sc.sites)
    for site in sc.sites:
        batches = [
            e.message for e in events if e.kind == "plots" and e.message.radar_id == site.radar_id
        ]
        ev_times = [
            e.time for e in events if e.kind == "plots" and e.message.radar_id == site.radar_id
        ]
        n = site.n_sectors
        assert len(batches) >= n and len(batches) % n == 0
        assert [b.seq for b in batches] == list(range(len(batches)))
        assert ev_times == [b.time_end for b in batches]
        for i, b in enumerate(batches):
            assert b.scan == i // n
            assert b.sector_start == pytest.approx((i % n) * TWO_PI / n, abs=1e-12)
            assert b.sector_width == pytest.approx(TWO_PI / n)
            assert b.time_end - b.time_start == pytest.approx(site.scan_period * 1e9 / n, abs=2)
            if i:
                assert b.time_start == batches[i - 1].time_end
            t = b.column("time")
            if len(t):
                assert (np.diff(t) >= 0).all()
                assert t[0] >= b.time_start and t[-1] <= b.time_end
        for k in range(len(batches) // n):
            scan = batches[k * n : (k + 1) * n]
            assert sum(b.sector_width for b in scan) == pytest.approx(TWO_PI)
            assert scan[-1].time_end - scan[0].time_start == pytest.approx(
                site.scan_period * 1e9, abs=2
            )


def test_range_gate_and_horizon():
    sc = build_scenario("regional", duration=60, seed=2, targets=80)
    sim = Simulator(sc, seed=1)
    for i, scan in enumerate(sim.scans()):
        site = sc.sites[scan.radar_index]
        cfg = sc.sensors[scan.radar_index]
        m = scan.target_id >= 0
        if not m.any():
            continue
        _, el, r, _ = truth_geometry(sim, site, scan.time[m], scan.target_id[m])
        assert (r >= site.min_range).all() and (r <= site.max_range).all()
        assert (el >= cfg.min_elevation - 1e-9).all()
        if i > 40:
            break
