"""``skyfuse eval FILE`` on a biased simulated recording: bias estimates
against the recording's truth (``Truth.radar_bias``) over time and at the end, duplicate
tracks per aircraft and RMSE with registration on and off; and the airborne / surface
split of the label measures, checked against a direct count of the recording's plots."""

from __future__ import annotations

import math

import numpy as np
from service_support import BIASED_REGIONAL, BIASED_TRUTH
from skyfuse.fusion.registration import RegistrationConfig
from skyfuse.schemas import PlotBatch, Truth
from skyfuse.services.evaluation.recording import evaluate_recording
from skyfuse.services.evaluation.registration_eval import duplicate_counts
from skyfuse.services.recording.mcap_io import iter_recording


def test_eval_reports_biases_against_truth_and_registration_on_off(simulated_recording):
    rec = simulated_recording(*BIASED_REGIONAL)
    truth = {}
    for r in iter_recording(rec):
        if isinstance(r.message, Truth):
            truth.update({b.radar_id: b for b in r.message.radar_bias})
    assert set(truth) == set(BIASED_TRUTH)  # what the simulator was told
    s = evaluate_recording(rec, registration=RegistrationConfig(reference=["LYBE"]))
    rv = s["registration_vs_truth"]
    for rid, (az, rng) in BIASED_TRUTH.items():
        assert rv["truth"][rid]["azimuth"] == az and rv["truth"][rid]["range"] == rng
    final = {r["radar_id"]: r for r in rv["final"]}
    for rid, (az, rng) in BIASED_TRUTH.items():
        a, d = final[rid]["azimuth"], final[rid]["range"]
        assert a["truth"] == az and abs(a["estimate"] - az) <= 3.5 * a["sigma"]
        assert abs(a["z"] - (a["estimate"] - az) / a["sigma"]) < 0.02  # (rounded figures)
        assert abs(d["estimate"] - rng) <= 3.5 * d["sigma"] and d["truth"] == rng
        assert a["within_20pct_or_2sigma"] == (
            abs(a["error"]) <= max(0.2 * abs(az), 2 * a["sigma"]) + 1e-3
        )
    # over time: one sample a minute, the azimuth uncertainty shrinking
    t = [row["t_s"] for row in rv["series"]]
    assert len(t) >= 3 and np.all(np.diff(t) >= 59.0)
    sig = [
        row["radars"]["LYVR"]["azimuth_deg"][1] for row in rv["series"] if "LYVR" in row["radars"]
    ]
    assert sig[-1] < sig[0]
    # registration on against off: the biases cost accuracy, the correction wins it back
    off = s["registration_off"]
    assert off["position_rmse_m"] > 1.05 * s["truth"]["position_rmse_m"]
    assert rv["duplicates"]["assigned_target_samples"] > 0
    assert (
        off["duplicates"]["duplicates_per_aircraft"] >= rv["duplicates"]["duplicates_per_aircraft"]
    )


def test_eval_splits_label_measures_by_traffic_class(simulated_recording):
    rec = simulated_recording(*BIASED_REGIONAL)
    alt, rng = [], []
    for r in iter_recording(rec):
        if isinstance(r.message, PlotBatch) and len(r.message):
            a = r.message.column("altitude")  # None for the 3-D radar (elevation)
            alt.append(np.full(len(r.message), np.nan) if a is None else np.asarray(a, float))
            rng.append(np.asarray(r.message.range, float))
    alt, rng = np.concatenate(alt), np.concatenate(rng)
    fl10, nm2 = 10 * 100 * 0.3048, 2 * 1852.0  # FL 10 in m, 2 NM in m
    s = evaluate_recording(rec, registration=RegistrationConfig(mode="off"))
    split = s["labels_by_traffic"]
    assert split["all"]["plots"] == len(alt) == s["labels"]["plots"]
    assert split["airborne"]["plots"] == int(((alt >= fl10) & (rng >= nm2)).sum())
    assert split["surface"]["plots"] == int((alt < fl10).sum())
    assert split["all"]["aircraft"] == s["labels"]["aircraft"]
    assert "registration_off" not in s  # registration off: nothing to compare


def test_duplicate_counts_brute_force():
    rng = np.random.default_rng(2)
    targets = rng.uniform(0, 50_000, (6, 2))
    tracks = np.vstack([targets + rng.normal(0, 100, (6, 2)), targets[:2] + 900.0,
                        [[1e6, 1e6]]])  # fmt: skip
    dup, assigned = duplicate_counts(targets, tracks, 2000.0)
    # by hand: every target has its own track; the two tracks 1.27 km off targets 0, 1
    # are duplicates; the far one is neither
    assert (dup, assigned) == (2, 6)
    assert duplicate_counts(targets, np.zeros((0, 2)), 2000.0) == (0, 0)
    assert math.isclose(np.hypot(900, 900), 1272.79, rel_tol=1e-5)
