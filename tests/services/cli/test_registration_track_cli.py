"""``skyfuse track`` with online sensor registration: on a simulated
three-radar recording with two biased radars, the estimates published in the JSON
summary recover the simulated biases (the simulator's parameters, never seen by the
estimator) within their stated uncertainty; the reference stays at 0; with
``--registration off`` nothing is estimated."""

from __future__ import annotations

import json
import math
from pathlib import Path

from service_support import BIASED_REGIONAL, BIASED_TRUTH
from skyfuse.services.cli.main import main as skyfuse_main


def _track(rec: Path, tmp_path: Path, *flags: str) -> dict:
    out = tmp_path / "s.json"
    args = ["track", str(rec), "--out", str(tmp_path / "t.mcap"), "--json", str(out)]
    assert skyfuse_main([*args, "--no-progress", *flags]) == 0
    return json.loads(out.read_text())


def test_track_recovers_two_radars_biases_and_publishes_them(tmp_path, simulated_recording):
    rec = simulated_recording(*BIASED_REGIONAL)
    s = _track(rec, tmp_path, "--registration-reference", "LYBE")
    reg = s["registration"]
    assert reg["mode"] == "on"
    est = {r["radar_id"]: r for r in reg["radars"]}
    assert set(est) == {"LYBE", "LYVR", "LRTR"}
    ref = est["LYBE"]
    assert ref["reference"] and ref["azimuth"] == ref["range"] == ref["azimuth_sigma"] == 0.0
    for rid, (az_deg, rng_m) in BIASED_TRUTH.items():
        e = est[rid]
        assert e["pairs_used"] > 50, e
        az, s_az = e["azimuth"], e["azimuth_sigma"]
        assert 0 < s_az < math.radians(0.03), e  # informative
        assert abs(az - math.radians(az_deg)) <= 3.5 * s_az, e
        assert 0 < e["range_sigma"] < 40.0, e
        assert abs(e["range"] - rng_m) <= 3.5 * e["range_sigma"], e
        # the time offset (only LYVR's is 50 ms) is weakly observable: within 3.5σ
        t_true = 0.05 if rid == "LYVR" else 0.0
        assert abs(e["time"] - t_true) <= 3.5 * e["time_sigma"], e
    assert s["plots_near_radar"] == 0  # regional radars see no aircraft overhead


def test_track_registration_off_estimates_nothing(tmp_path, simulated_recording):
    rec = simulated_recording(*BIASED_REGIONAL)
    s = _track(rec, tmp_path, "--registration", "off")
    assert s["registration"]["mode"] == "off"
    assert s["registration"]["radars"] == []
