"""The simulator's report sensors (fusion.sim.reports): ADS-B and multilateration errors
against their configured error models (Monte Carlo over many reports, truth from the
scenario's trajectories through pymap3d), the share of non-equipped aircraft, the
coverage polygon and the report cycles' timing.

References written here, independently of the simulator: the NACp → EPU values of RTCA
DO-260B (EPU 30 m for NACp 9, 0.3 NM for NACp 6, a 95 % radius of a circular Gaussian:
σ = EPU / √(−2 ln 0.05)), NACv 2 → 3 m/s, the multilateration σ(ρ) = √(σ_c² + (g ρ)²).
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from scipy import stats
from skyfuse.fusion.sim import Simulator, build_scenario

R95 = math.sqrt(-2.0 * math.log(0.05))
SIG9, SIG6 = 30.0 / R95, 0.3 * 1852.0 / R95
SIG_V = 3.0 / R95


def _scenario(**kw):
    params = dict(adsb=True, mlat=True, adsb_poor_fraction=0.25, adsb_equipped_fraction=0.6,
                  mlat_radius=60_000.0)  # fmt: skip
    params.update(kw)
    return build_scenario("regional", seed=5, duration=40.0, targets=300, **params)


@pytest.fixture(scope="module")
def run():
    sc = _scenario()
    sim = Simulator(sc)
    return sc, {rid: list(sim.scans(rid)) for rid in ("ADSB", "MLAT")}


def _truth(sc, scans):
    """Per report: the aircraft's index and its true lat/lon/h at the report time."""
    tid = np.concatenate([s.target_id for s in scans])
    idx = np.searchsorted(sc.targets.target_id, tid)
    t = (np.concatenate([s.time for s in scans]) - sc.start_time) * 1e-9
    lat, lon, h = sc.geodetic(idx, t)
    return idx, t, np.asarray(lat), np.asarray(lon), np.asarray(h)


def _cat(scans, name):
    return np.concatenate([getattr(s, name) for s in scans])


def test_adsb_position_and_velocity_errors_follow_nacp_and_nacv(run):
    sc, scans = run
    s = scans["ADSB"]
    idx, t, lat, lon, h = _truth(sc, s)
    e, n, _ = pymap3d.geodetic2enu(_cat(s, "lat"), _cat(s, "lon"), h, lat, lon, h)
    sigma = _cat(s, "sigma")
    assert set(np.round(sigma, 6)) == {round(SIG9, 6), round(SIG6, 6)}
    for sig in (SIG9, SIG6):
        sel = np.isclose(sigma, sig)
        assert sel.sum() > 500
        for err in (e[sel], n[sel]):
            # mean 0 and variance σ² (99.9 % bounds of the sample mean and variance)
            assert abs(err.mean()) < 3.3 * sig / math.sqrt(sel.sum())
            chi2 = (err**2).sum() / sig**2
            assert stats.chi2.ppf(5e-4, sel.sum()) < chi2 < stats.chi2.ppf(1 - 5e-4, sel.sum())
    # one NACp per aircraft, a quarter of them poor
    poor = np.isclose(sigma, SIG6)
    assert not np.intersect1d(idx[poor], idx[~poor]).size
    share = len(np.unique(idx[poor])) / len(np.unique(idx))
    assert abs(share - 0.25) < 3.3 * math.sqrt(0.25 * 0.75 / len(np.unique(idx)))
    # velocity: the truth's east/north velocity from positions ±0.1 s apart
    la, lo, hh = sc.geodetic(idx, t + 0.1)
    lb, lob, hb = sc.geodetic(idx, t - 0.1)
    ve, vn, _ = pymap3d.geodetic2enu(la, lo, hh, lb, lob, hb)
    for err in (_cat(s, "v_east") - ve / 0.2, _cat(s, "v_north") - vn / 0.2):
        chi2 = (err**2).sum() / SIG_V**2
        assert stats.chi2.ppf(5e-4, len(err)) < chi2 < stats.chi2.ppf(1 - 5e-4, len(err))
    assert np.allclose(_cat(s, "sigma_velocity"), SIG_V)


def test_adsb_reports_only_the_equipped_share_of_mode_s_aircraft(run):
    sc, scans = run
    idx = np.unique(_truth(sc, scans["ADSB"])[0])
    mode_s = sc.targets.mode_s >= 0
    assert mode_s[idx].all()  # ADS-B needs a 24-bit address
    # every equipped aircraft alive for 10 s or more is reported (P_D 0.95, ≥ 10 cycles):
    # the share of the Mode-S aircraft reported is the equipped share
    alive = np.minimum(sc.targets.t_death, 40.0) - np.maximum(sc.targets.t_birth, 0.0)
    whole = mode_s & (alive >= 10.0)
    k = whole.sum()
    share = np.isin(np.flatnonzero(whole), idx).sum() / k
    assert k > 100 and abs(share - 0.6) < 3.3 * math.sqrt(0.6 * 0.4 / k), (share, k)
    # and the MLAT reports every transponder inside its coverage, equipped or not
    mlat = np.unique(_truth(sc, scans["MLAT"])[0])
    assert np.setdiff1d(mlat, idx).size > 0


def test_mlat_error_grows_with_distance_and_stays_in_its_polygon(run):
    sc, scans = run
    s = scans["MLAT"]
    site = next(x for x in sc.sites if x.radar_id == "MLAT")
    _, _, lat, lon, h = _truth(sc, s)
    e, n, _ = pymap3d.geodetic2enu(lat, lon, h, site.lat, site.lon, site.alt)
    rho = np.hypot(e, n)
    sig = np.sqrt(5.0**2 + (2.5e-3 * rho) ** 2)
    assert np.allclose(_cat(s, "sigma"), sig)
    for err in (_cat(s, "x") - e, _cat(s, "y") - n):
        chi2 = ((err / sig) ** 2).sum()
        assert stats.chi2.ppf(5e-4, len(err)) < chi2 < stats.chi2.ppf(1 - 5e-4, len(err))
    near, far = rho < 15_000.0, rho > 35_000.0
    assert near.sum() > 100 and far.sum() > 50
    assert np.std((_cat(s, "x") - e)[far]) > 1.8 * np.std((_cat(s, "x") - e)[near])
    # inside the regular octagon of circumradius R = 60 km (vertices at bearings k·45°):
    # the distance along the bearing of the nearest edge's midpoint is ≤ R cos 22.5°
    bearing = np.arctan2(e, n)
    off = bearing % (math.pi / 4) - math.pi / 8
    assert (rho * np.cos(off) <= 60_000.0 * math.cos(math.pi / 8) + 1.0).all()
    # and aircraft outside it are not reported although the range ring covers them
    alive_out = _outside_octagon_alive(sc, site, 60_000.0)
    assert alive_out > 0


def _outside_octagon_alive(sc, site, radius) -> int:
    """Aircraft alive at t = 20 s between the octagon and the 80-km range ring."""
    idx = np.flatnonzero(sc.targets.alive(20.0))
    lat, lon, h = sc.geodetic(idx, np.full(idx.size, 20.0))
    e, n, _ = pymap3d.geodetic2enu(lat, lon, h, site.lat, site.lon, site.alt)
    rho = np.hypot(e, n)
    return int(((rho > radius) & (rho < 75_000.0)).sum())


def test_report_cycles_timing(run):
    sc, scans = run
    for rid, period in (("ADSB", 1.0), ("MLAT", 1.0)):
        s = scans[rid]
        assert [x.scan for x in s] == list(range(40))
        last = {}
        for x in s:
            assert x.time_start == sc.start_time + round(x.scan * period * 1e9)
            assert x.time_end - x.time_start == round(period * 1e9) and x.n_sectors == 1
            assert (np.diff(x.time) >= 0).all()
            assert (x.time >= x.time_start).all() and (x.time < x.time_end).all()
            assert len(np.unique(x.target_id)) == len(x)  # one report per aircraft a cycle
            for tid, t in zip(x.target_id.tolist(), x.time.tolist(), strict=True):
                if tid in last:  # each aircraft at its own phase of the cycle
                    gap = (t - last[tid][1]) / 1e9 / (x.scan - last[tid][0])
                    assert gap == pytest.approx(period, abs=1e-8)
                last[tid] = (x.scan, t)
        phases = np.array([t for _, t in last.values()]) % round(period * 1e9)
        assert stats.kstest(phases / (period * 1e9), "uniform").pvalue > 1e-3


def test_report_batches_on_the_wire():
    """Simulator.run: one PlotBatch per cycle with the report columns, a site per sensor."""
    sc = _scenario(mlat=False)
    events = list(Simulator(sc).run(radars=["ADSB"], truth=False))
    site = events[0].message
    assert site.kind == "wgs84" and site.detection == "reports" and site.timing == "plots"
    batches = [e.message for e in events[1:]]
    assert len(batches) == 40 and all(b.sector_width == 2 * math.pi for b in batches)
    b = batches[10]
    assert b.is_geodetic and len(b.sigma) == len(b) and b.mode_s and b.callsign
    assert all(e.time == e.message.time_end for e in events[1:])
