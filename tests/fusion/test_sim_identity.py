"""Simulated identity (fusion.sim.identity): callsigns, code changes, garbled replies,
flight levels and downlinked parameters on the plots of the regional scenario, checked
against the scenario's truth (positions, velocities, turn rates) and the parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats
from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.schemas.identity import CALLSIGN_RE

FL_M = 30.48


def plots_of(sc, seed=1):
    """Every plot of a run as a dict of numpy columns (+ radar kind, time s)."""
    rows: dict[str, list] = {}
    kinds = {s.radar_id: s.kind for s in sc.sites}
    for ev in Simulator(sc, seed=seed).run(truth=False):
        if ev.kind != "plots" or not len(ev.message):
            continue
        b = ev.message
        n = len(b)
        rows.setdefault("kind", []).extend([str(kinds[b.radar_id])] * n)
        rows.setdefault("t", []).extend(((b.column("time") - sc.start_time) * 1e-9).tolist())
        for name in ("target_id", "mode_s", "mode_3a", "altitude", "flight_level", "callsign",
                     "mode_3a_garbled", "flight_level_garbled", "ground_speed", "true_track",
                     "track_angle_rate", "roll_angle", "inertial_vertical_rate",
                     "baro_vertical_rate", "range", "azimuth", "time"):  # fmt: skip
            col = b.column(name)
            if col is None:  # an absent column: its null value
                null = {"callsign": "", "mode_s": -1, "mode_3a": -1}.get(name, math.nan)
                col = np.full(n, False if name.endswith("garbled") else null)
            rows.setdefault(name, []).extend(col.tolist())
    return {k: np.asarray(v) for k, v in rows.items()}


@pytest.fixture(scope="module")
def run():
    sc = build_scenario("regional", seed=5, duration=240.0, targets=30, code_change_fraction=0.5,
                        garble_probability=0.05, ehs_fraction=1.0)  # fmt: skip
    return sc, plots_of(sc)


def test_mode_s_aircraft_carry_a_callsign_and_a_flight_level(run):
    _, p = run
    tgt = p["target_id"] >= 0
    mode_s = p["mode_s"] >= 0
    assert (mode_s <= tgt).all()  # clutter carries nothing
    assert (p["callsign"][~tgt] == "").all() and np.isnan(p["flight_level"][~tgt]).all()
    assert all(CALLSIGN_RE.match(c) for c in p["callsign"][mode_s])
    # one callsign per aircraft, different aircraft different callsigns
    by_target = {
        t: set(p["callsign"][p["target_id"] == t]) for t in np.unique(p["target_id"][mode_s])
    }
    assert all(len(v) == 1 for v in by_target.values())
    assert len({next(iter(v)) for v in by_target.values()}) == len(by_target)
    # 2-D radars: the flight level is the Mode C altitude (ISA: pressure altitude = height)
    two_d = mode_s & (p["kind"] == "2d") & ~p["flight_level_garbled"]
    assert two_d.sum() > 100
    np.testing.assert_allclose(
        p["flight_level"][two_d], np.round(p["altitude"][two_d] / FL_M * 4) / 4
    )
    # a garbled level gives no altitude (what the ASTERIX reader makes of it)
    garbled = mode_s & (p["kind"] == "2d") & p["flight_level_garbled"]
    assert garbled.sum() > 5 and np.isnan(p["altitude"][garbled]).all()


def test_code_changes_take_effect_at_their_time_and_garbled_replies_are_flagged(run):
    sc, p = run
    tg = sc.targets
    changed = np.flatnonzero(np.isfinite(tg.mode_3a_change_time))
    assert changed.size >= 5  # half of the ≈24 aircraft with a code
    seen_after = 0
    for i in changed:
        mine = (p["target_id"] == tg.target_id[i]) & ~p["mode_3a_garbled"]
        before = mine & (p["t"] < tg.mode_3a_change_time[i])
        after = mine & (p["t"] >= tg.mode_3a_change_time[i])
        assert (p["mode_3a"][before] == tg.mode_3a[i]).all()
        assert (p["mode_3a"][after] == tg.mode_3a_after[i]).all()
        assert tg.mode_3a_after[i] != tg.mode_3a[i]
        seen_after += after.any()
    assert seen_after >= 3
    # garbled replies: about 5 % of the codes, each one bit off the aircraft's code
    coded = p["mode_3a"] >= 0
    k, n = int(p["mode_3a_garbled"][coded].sum()), int(coded.sum())
    assert stats.binomtest(k, n, 0.05).pvalue > 1e-3
    garbled = np.flatnonzero(p["mode_3a_garbled"])
    for j in garbled:
        i = np.flatnonzero(tg.target_id == p["target_id"][j])[0]
        true = tg.mode_3a_after[i] if p["t"][j] >= tg.mode_3a_change_time[i] else tg.mode_3a[i]
        assert bin(int(p["mode_3a"][j]) ^ int(true)).count("1") == 1
    bad_fl = p["flight_level_garbled"]
    assert stats.binomtest(int(bad_fl[coded].sum()), n, 0.05).pvalue > 1e-3


def test_downlinked_parameters_follow_the_truth(run):
    sc, p = run
    sim = Simulator(sc, seed=1)
    ehs = np.flatnonzero(np.isfinite(p["ground_speed"]))
    assert ehs.size > 200
    rng = np.random.default_rng(0)
    for j in rng.choice(ehs, 60, replace=False):
        tr = sim.truth_at(np.array([int(p["time"][j])]))
        i = np.flatnonzero(tr["target_id"] == p["target_id"][j])[0]
        ve, vn, vu = tr["vel_east"][0, i], tr["vel_north"][0, i], tr["vel_up"][0, i]
        assert p["ground_speed"][j] == pytest.approx(math.hypot(ve, vn), abs=0.5)
        d_trk = (p["true_track"][j] - math.atan2(ve, vn) + math.pi) % (2 * math.pi) - math.pi
        assert abs(d_trk) < 2e-3
        assert p["inertial_vertical_rate"][j] == pytest.approx(vu, abs=0.05)
        assert p["baro_vertical_rate"][j] == p["inertial_vertical_rate"][j]


def test_turn_rate_and_roll_angle_of_turning_aircraft(run):
    """In a turn segment the track rate is the segment's turn rate ω (the trajectory
    builder's, an independent number) and the roll is that of a coordinated turn."""
    sc, p = run
    tg = sc.targets
    checked = 0
    for j in np.flatnonzero(np.isfinite(p["track_angle_rate"])):
        i = np.flatnonzero(tg.target_id == p["target_id"][j])[0]
        k = int(np.searchsorted(tg.seg_t0[i], p["t"][j], side="right") - 1)
        if k < 0 or tg.seg_omega[i, k] == 0.0:
            continue
        t_in = p["t"][j] - tg.seg_t0[i, k]
        if t_in < 1.0 or tg.seg_t0[i, k + 1] - p["t"][j] < 1.0:
            continue  # the ±0.5 s difference spans a segment boundary
        omega = tg.seg_omega[i, k]  # counter-clockwise in the plane: track rate is -ω
        assert p["track_angle_rate"][j] == pytest.approx(-omega, rel=0.02, abs=2e-4)
        want = math.atan(p["ground_speed"][j] * p["track_angle_rate"][j] / 9.80665)
        assert p["roll_angle"][j] == pytest.approx(want, abs=1e-12)
        checked += 1
    assert checked > 20


def test_identity_never_changes_the_plots_of_a_seed():
    kw = {"seed": 2, "duration": 60.0, "targets": 15}
    a = plots_of(build_scenario("regional", **kw))
    b = plots_of(build_scenario("regional", code_change_fraction=1.0, garble_probability=0.5,
                                ehs_fraction=1.0, **kw))  # fmt: skip
    for name in ("time", "range", "azimuth", "target_id", "mode_s"):
        np.testing.assert_array_equal(a[name], b[name])
    assert (a["mode_3a"] != b["mode_3a"]).any()
