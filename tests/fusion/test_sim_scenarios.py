"""Named scenarios: they build and run, carry the sources' geometry, are deterministic, and
reject bad parameters with errors that name them."""

from __future__ import annotations

import itertools
import math
from datetime import UTC, datetime

import numpy as np
import pymap3d
import pytest
from scipy import stats
from skyfuse.fusion.sim import SCENARIOS, Simulator, build_scenario, scenario_parameters
from skyfuse.fusion.sim.trajectories import G0
from skyfuse.schemas import FrameKind, PlotBatch, RadarSite, Truth, keys

EXPECTED = {
    "thesis-stt", "thesis-mtt-5", "thesis-mtt-15", "thesis-mtt-50",
    "lm-ipf-2", "lm-ipf-15", "crossing-4g", "regional",
}  # fmt: skip


def test_scenario_names():
    assert set(SCENARIOS) == EXPECTED
    assert all(isinstance(d, str) and d for d in SCENARIOS.values())


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_every_scenario_builds_and_runs_briefly(name):
    duration = 20.0 if name == "regional" else 8.0
    sc = build_scenario(name, seed=4, duration=duration)
    assert sc.name == name and sc.duration == duration and sc.n_targets >= 1
    assert sc.params["seed"] == 4 and sc.params["duration"] == duration
    assert all(isinstance(s, RadarSite) for s in sc.sites)
    assert sc.frame.kind == (FrameKind.STEREOGRAPHIC if name == "regional" else FrameKind.PLANAR)
    events = list(Simulator(sc, seed=4).run())
    kinds = {e.kind for e in events}
    assert kinds == {"site", "plots", "truth"}
    for e in events:
        assert e.time >= sc.start_time
        if e.kind == "plots":
            assert isinstance(e.message, PlotBatch)
            assert e.topic == keys.radar_plots(e.message.radar_id)
            assert e.time == e.message.time_end <= sc.start_time + duration * 1e9 + 1
        elif e.kind == "truth":
            assert isinstance(e.message, Truth) and e.topic == keys.SIM_TRUTH
        else:
            assert e.topic == keys.radar_site(e.message.radar_id)
    assert sum(len(e.message) for e in events if e.kind == "plots") > 0
    # metadata records every parameter
    assert set(scenario_parameters(name)) <= set(sc.params)
    assert sc.metadata()["scenario"] == name


def test_thesis_mtt_targets_reach_the_centre_at_scan_20():
    sc = build_scenario("thesis-mtt-15", sigma_v=0.0)
    sim = Simulator(sc, seed=0)
    t20 = sc.start_time + 20 * 10**9
    d = sim.truth_at(np.array([t20, sc.start_time + 10**9]), geodetic=False)
    np.testing.assert_allclose(d["x"][0], 500.0, atol=1e-9)
    np.testing.assert_allclose(d["y"][0], 500.0, atol=1e-9)
    # scan 1: 475 m out, spaced 10° over a 140° arc, speed 25 m/s
    r1 = np.hypot(d["x"][1] - 500, d["y"][1] - 500)
    np.testing.assert_allclose(r1, 475.0)
    ang = np.degrees(np.arctan2(d["y"][1] - 500, d["x"][1] - 500))
    np.testing.assert_allclose(np.diff(ang), 10.0)
    np.testing.assert_allclose(np.hypot(d["vx"][1], d["vy"][1]), 25.0)
    assert build_scenario("thesis-mtt-50").params["spacing_deg"] == 7.0


def test_thesis_mtt_velocity_randomisation_gives_variance_2r_at_the_centre():
    off = []
    for seed in range(60):
        sc = build_scenario("thesis-mtt-5", seed=seed)
        p, _ = sc.targets.state(np.full(5, 20.0))
        off.append(p[:, :2] - 500.0)
    off = np.concatenate(off).ravel()
    s2 = (off**2).sum() / 50.0
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], off.size)
    assert lo <= s2 <= hi


def test_lm_ipf_trajectories_are_the_same_every_run():
    a = build_scenario("lm-ipf-15", seed=1)
    b = build_scenario("lm-ipf-15", seed=2)
    np.testing.assert_array_equal(a.targets.seg_v0, b.targets.seg_v0)
    c = build_scenario("lm-ipf-15", seed=1, trajectory_seed=9)
    assert not np.array_equal(a.targets.seg_v0, c.targets.seg_v0)
    # start on the r = 450 circle, 10° apart; pass c + δ at scan 20, δ ~ N(0, 2R)
    p0, _ = a.targets.state(np.zeros(15))
    np.testing.assert_allclose(np.hypot(p0[:, 0] - 500, p0[:, 1] - 500), 450.0)
    d = []
    for ts in range(40):
        sc = build_scenario("lm-ipf-2", trajectory_seed=ts)
        p20, _ = sc.targets.state(np.full(2, 20.0))
        d.append(p20[:, :2] - 500.0)
    d = np.concatenate(d).ravel()
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], d.size)
    assert lo <= (d**2).sum() / 50.0 <= hi
    # measurements differ between seeds
    za = np.concatenate([s.x for s in Simulator(a, seed=1).scans()])
    zb = np.concatenate([s.x for s in Simulator(a, seed=2).scans()])
    assert len(za) != len(zb) or not np.array_equal(za, zb)


def test_crossing_4g_tracks_cross_in_opposite_4g_turns():
    sc = build_scenario("crossing-4g")
    sim = Simulator(sc, seed=0)
    t = np.arange(0.0, 72.0, 0.05)
    d = sim.truth_at(sc.start_time + np.rint(t * 1e9).astype(np.int64), geodetic=False)
    # the two targets change sides: azimuth order from the radar swaps
    az = np.arctan2(d["x"], d["y"])
    diff = az[:, 1] - az[:, 0]
    assert diff[0] > 0 and diff[-1] < 0
    t_cross = t[np.flatnonzero(np.diff(np.sign(diff)))[0]]
    assert 34.0 < t_cross < 42.0
    # lateral acceleration 4 g during 34-42 s, 0 outside; speed 311 m/s throughout
    acc = np.hypot(*np.gradient(np.stack([d["vx"], d["vy"]]), t, axis=1))
    inside = (t > 34.2) & (t < 41.8)
    outside = (t < 33.8) | (t > 42.2)
    np.testing.assert_allclose(acc[inside], 4 * G0, rtol=1e-3)
    assert acc[outside].max() < 1e-6
    np.testing.assert_allclose(np.hypot(d["vx"], d["vy"]), 311.0)
    # initial range 50 km at 45° and 46.1°
    np.testing.assert_allclose(np.hypot(d["x"][0], d["y"][0]), 50_000.0)
    np.testing.assert_allclose(np.degrees(az[0]), [45.0, 46.1])
    assert sc.sites[0].sigma_azimuth == pytest.approx(2.5e-3)
    assert build_scenario("crossing-4g", sigma_az_mrad=6).sites[0].sigma_azimuth == pytest.approx(
        6e-3
    )


def test_regional_sites_and_traffic():
    sc = build_scenario("regional", seed=1)
    assert len(sc.sites) >= 3 and {s.kind for s in sc.sites} == {"2d", "3d"}
    for a, b in itertools.combinations(sc.sites, 2):
        _, _, r = pymap3d.geodetic2aer(b.lat, b.lon, b.alt, a.lat, a.lon, a.alt)
        assert 50e3 <= r <= 150e3, (a.radar_id, b.radar_id, r)
    assert all(4.0 <= s.scan_period <= 12.0 and s.n_sectors == 16 for s in sc.sites)
    assert all(s.clutter_density > 0 for s in sc.sites)
    tg = sc.targets
    assert 20 <= sc.n_targets <= 200 and sc.n_targets == 40
    assert (tg.t_birth > 0).any() and (tg.t_birth == 0).any()  # entering, already there
    assert (tg.t_death < sc.duration).any()  # leaving
    assert (tg.seg_omega != 0).any()  # turning
    assert (np.abs(tg.seg_v0[..., 2]) > 1).any()  # climbing / descending
    assert (tg.mode_s >= 0).any() and (tg.mode_s < 0).any()
    assert build_scenario("regional", targets=150, duration=30).n_targets == 150
    # truth velocities east/north match the displacement over one second (pymap3d ENU)
    sim = Simulator(sc, seed=1)
    t = sc.start_time + np.array([100 * 10**9, 101 * 10**9])
    d = sim.truth_at(t)
    alive = d["alive"].all(0)
    e, n, _ = pymap3d.geodetic2enu(
        d["lat"][1], d["lon"][1], d["alt"][1], d["lat"][0], d["lon"][0], d["alt"][0]
    )
    ve = 0.5 * (d["vel_east"][0] + d["vel_east"][1])
    vn = 0.5 * (d["vel_north"][0] + d["vel_north"][1])
    straight = alive & (np.abs(d["vx"][0] - d["vx"][1]) < 1e-9)
    assert straight.sum() > 5
    np.testing.assert_allclose(e[straight], ve[straight], atol=0.05)
    np.testing.assert_allclose(n[straight], vn[straight], atol=0.05)


def test_regional_mode_s_column():
    sc = build_scenario("regional", duration=30, seed=2)
    batches = [e.message for e in Simulator(sc).run() if e.kind == "plots" and len(e.message)]
    addr = {
        int(t): int(m) for b in batches for t, m in zip(b.column("target_id"), b.column("mode_s"))
    }
    for tid, m in addr.items():
        expected = -1 if tid < 0 else int(sc.targets.mode_s[tid])
        assert m == expected


def _dump(name, seed, sim_seed, **kw):
    sc = build_scenario(name, seed=seed, **kw)
    return [
        (e.time, e.topic, e.message.to_json_bytes()) for e in Simulator(sc, seed=sim_seed).run()
    ]


@pytest.mark.parametrize(("name", "kw"), [("thesis-stt", {}), ("regional", {"duration": 20})])
def test_same_seed_same_messages_different_seed_different(name, kw):
    a = _dump(name, 5, 5, **kw)
    assert a == _dump(name, 5, 5, **kw)
    assert a != _dump(name, 5, 6, **kw)
    assert a != _dump(name, 6, 5, **kw)


def test_scans_and_messages_carry_the_same_numbers():
    sc = build_scenario("regional", duration=24, seed=3)
    sim = Simulator(sc, seed=8)
    scans = {(s.radar_id, s.scan): s for s in sim.scans()}
    batches = [e.message for e in sim.run() if e.kind == "plots"]
    for rid_scan, s in scans.items():
        bs = [b for b in batches if (b.radar_id, b.scan) == rid_scan]
        assert len(bs) == s.n_sectors
        np.testing.assert_array_equal(np.concatenate([b.column("time") for b in bs]), s.time)
        np.testing.assert_array_equal(np.concatenate([b.column("range") for b in bs]), s.range)
        np.testing.assert_array_equal(
            np.concatenate([b.column("target_id") for b in bs]), s.target_id
        )


@pytest.mark.parametrize(
    ("call", "needle"),
    [
        (lambda: build_scenario("nope"), "nope"),
        (lambda: build_scenario("thesis-stt", wind=3), "'wind'"),
        (lambda: build_scenario("thesis-stt", p_detection=1.5), "'p_detection'"),
        (lambda: build_scenario("thesis-stt", p_detection="high"), "'p_detection'"),
        (lambda: build_scenario("thesis-stt", targets=2), "'targets'"),
        (lambda: build_scenario("crossing-4g", radar_kind="4d"), "'radar_kind'"),
        (lambda: build_scenario("crossing-4g", n_sectors=2.5), "'n_sectors'"),
        (lambda: build_scenario("regional", duration=-5), "'duration'"),
        (lambda: build_scenario("regional", seed=-1), "'seed'"),
        (lambda: build_scenario("regional", radars=7), "'radars'"),
        (lambda: build_scenario("thesis-mtt-5", start_time="2026-01-01T00:00:00"), "'start_time'"),
        (lambda: Simulator(build_scenario("thesis-mtt-5"), seed=-2), "seed"),
        (lambda: list(Simulator(build_scenario("thesis-mtt-5")).scans("other")), "other"),
    ],
)
def test_bad_parameters_raise_value_errors_naming_them(call, needle):
    with pytest.raises(ValueError, match=needle):
        call()


def test_unknown_names_list_the_valid_choices():
    with pytest.raises(ValueError, match="thesis-mtt-15") as e:
        build_scenario("nope")
    assert "regional" in str(e.value)
    with pytest.raises(ValueError, match="p_detection"):
        build_scenario("thesis-stt", wind=3)


def test_start_time_parameter():
    sc = build_scenario("thesis-mtt-5", start_time="2027-06-01T12:00:00Z")
    ref = datetime(2027, 6, 1, 12, tzinfo=UTC).timestamp()
    assert sc.start_time == int(ref) * 10**9
    first = next(s for s in Simulator(sc).scans())
    assert first.time_start == sc.start_time + 10**9
    assert math.isclose(build_scenario("thesis-mtt-5").start_time / 1e9, 1_767_225_600)


def test_run_for_one_radar_gives_the_same_batches_as_the_full_run():
    sc = build_scenario("regional", duration=24, seed=3)
    full = [e for e in Simulator(sc).run() if e.kind != "truth"]
    one = list(Simulator(sc).run(["LYVR"], truth=False))
    want = [e for e in full if e.message.radar_id == "LYVR"]
    assert [e.message.to_json_bytes() for e in one] == [e.message.to_json_bytes() for e in want]
    with pytest.raises(ValueError, match="XXXX"):
        list(Simulator(sc).run(["XXXX"]))


def test_regional_scenario_takes_up_to_six_radars_at_their_scan_periods():
    """Six radars: every radar scans at its own period, so over 60 s
    a radar makes ⌊60 / T⌋ (± 1 for its phase) revolutions; seven are refused."""

    sc = build_scenario("regional", seed=3, duration=60.0, targets=20, radars=6)
    ids = [s.site.radar_id for s in sc.sensors]
    assert ids == ["LYBE", "LYVR", "LRTR", "NOVISAD", "LDOS", "LHUD"]
    scans: dict[str, int] = {}
    for s in Simulator(sc).scans():
        scans[s.radar_id] = scans.get(s.radar_id, 0) + 1
    for sensor in sc.sensors:
        expected = 60.0 / sensor.site.scan_period
        assert abs(scans[sensor.site.radar_id] - expected) <= 1.0
    with pytest.raises(ValueError, match="radars"):
        build_scenario("regional", seed=3, duration=60.0, targets=20, radars=7)


def test_regional_steady_traffic_is_stationary():
    """traffic = steady: route starts uniform in (−L, D) give every instant the same
    expected number of aircraft in the air, P(alive at t) = L_i / (D + L_i) for every t
    (scenarios._steady_timing). The counts at seven instants must each lie within 4
    binomial σ of their mean; the default (mixed) traffic thins out over a long run."""
    duration = 3600.0
    times = np.linspace(0.0, duration, 7)
    for traffic, stationary in (("steady", True), ("mixed", False)):
        sc = build_scenario("regional", seed=5, duration=duration, targets=2000, traffic=traffic)
        birth, death = sc.targets.t_birth, sc.targets.t_death
        alive = np.array([((birth <= t) & (death >= t)).sum() for t in times])
        if not stationary:
            assert alive[-1] < 0.6 * alive[0]
            continue
        mean = alive.mean()
        p = mean / len(birth)
        sigma = np.sqrt(len(birth) * p * (1 - p))
        assert mean > 100
        assert np.all(np.abs(alive - mean) < 4 * sigma), (alive, mean, sigma)
