"""``skyfuse eval ... --reference``: the reference reader (ADS-B, multilateration), a
sensor's own tracks, the ground/airborne rule, and the command on a simulated recording
whose truth, written as ADS-B, stands in for the reference."""

from __future__ import annotations

import json

import asterix.generated as gen
import numpy as np
import pytest
from service_support import LEBL_SITES_TOML
from skyfuse.schemas import Truth
from skyfuse.services.asterix.cat010 import Cat010Report
from skyfuse.services.asterix.cat021 import Cat021Report
from skyfuse.services.cli.main import main
from skyfuse.services.evaluation.sensor_tracks import track_lives
from skyfuse.services.evaluation.surveillance_positions import ground_flags
from skyfuse.services.recording.mcap_io import iter_recording

FIELD_MONITORS = ["342383", "342384", "342385", "342386", "342387", "3433D5"]


# ---- pieces ---------------------------------------------------------------------------


def test_ground_flags_follow_the_documented_rule():
    r = [
        Cat021Report(0, 1, "2.6", 0.0, 41.0, 2.0, 1, ground=True, flight_level=3.0),
        Cat021Report(0, 1, "2.6", 0.0, 41.0, 2.0, 1, flight_level=1.0),  # on final: airborne
        Cat021Report(0, 1, "2.6", 0.0, 41.0, 2.0, 1, ground_speed_ms=12.0),  # taxiing
        Cat021Report(0, 1, "2.6", 0.0, 41.0, 2.0, 1, ground_speed_ms=70.0),
        Cat021Report(0, 1, "2.6", 0.0, 41.0, 2.0, 1),  # nothing known: airborne
        Cat010Report(0, 7, 0.0, typ=3),  # an SMR plot
        Cat010Report(0, 107, 0.0, typ=1, vx_ms=3.0, vy_ms=4.0),
        Cat010Report(0, 107, 0.0, typ=1, height_m=0.0),
    ]
    assert ground_flags(r).tolist() == [True, False, True, False, False, True, True, False]


def test_sensor_reports_that_are_no_updates_are_left_out():
    from collections import Counter

    from skyfuse.services.evaluation.sensor_tracks import _kept
    from skyfuse.services.evaluation.surveillance_positions import cat010_positions

    reps = [
        Cat010Report(0, 7, 0.0, typ=3, x_m=1.0, y_m=2.0, track_number=1),
        Cat010Report(0, 7, 0.0, typ=3, x_m=1.0, y_m=2.0, track_number=1, coasted=3),
        Cat010Report(0, 7, 0.0, typ=3, x_m=1.0, y_m=2.0, track_number=1, confirmed=False),
        Cat010Report(0, 107, 0.0, typ=1, x_m=1.0, y_m=2.0, track_number=1, rab=True),
        Cat010Report(0, 7, 0.0, typ=3, track_number=1, last=True),  # a track end
    ]
    counts = Counter()
    keep = _kept(reps, cat010_positions(reps), counts)
    assert keep.tolist() == [True, False, False, False, False]
    assert counts == {"coasted": 1, "not_confirmed": 1, "field_monitor": 1, "no_position": 1}


def test_track_numbers_start_a_new_life_after_an_end_or_a_long_silence():
    s = 10**9
    number = np.array([5, 5, 5, 7, 5, 5, 7])
    time = np.array([0, 1, 2, 2, 3, 40, 3]) * s
    end = np.array([False, False, True, False, False, False, False])
    lives = track_lives(np.zeros(7, np.int64), number, time, end, 30.0)
    # 5 lives on until its end report (3 reports), again until a 37 s silence, then anew;
    # 7 keeps one life; ids in order of first appearance in the file
    assert lives.tolist() == [0, 0, 0, 1, 2, 3, 1]
    other_source = track_lives(np.array([0, 1, 0, 0, 0, 0, 0]), number, time, end * 0, 30.0)
    assert other_source[1] != other_source[0] == other_source[2]


# ---- the LEBL recordings --------------------------------------------------------------


@pytest.fixture(scope="module")
def lebl(tmp_path_factory):
    from service_support import SHARED_DATA

    if not (SHARED_DATA / "lebl_20160510_2200_2215_adsb.ast").is_file():
        pytest.skip(f"{SHARED_DATA} has no LEBL recordings")
    sites = tmp_path_factory.mktemp("lebl") / "lebl.toml"
    sites.write_text(LEBL_SITES_TOML)
    return SHARED_DATA, sites


def test_reference_readers_on_the_lebl_recordings(lebl):
    from skyfuse.services.evaluation.reference import read_reference

    data, _ = lebl
    adsb = read_reference(data / "lebl_20160510_2200_2215_adsb.ast", date="2016-05-10")
    assert adsb.kind == "adsb" and len(adsb) == 19140 and len(np.unique(adsb.key)) == 29
    assert abs(adsb.ground.mean() - 0.374) < 0.002  # the survey's ground-bit share
    assert np.nanmedian(adsb.sigma) == pytest.approx(37.8, abs=0.1)  # NUCp 7
    mlat = read_reference(data / "lebl_20160510_2200_2215_mlat.ast", date="2016-05-10")
    assert mlat.kind == "mlat" and mlat.field_monitors == FIELD_MONITORS
    assert mlat.counts["field_monitor"] == 5220 and len(mlat) == 13298 - 5220
    assert len(np.unique(mlat.key)) == 20 and not set(FIELD_MONITORS) & {
        f"{k:06X}" for k in mlat.key.tolist()
    }
    mlat20 = read_reference(data / "lebl_20201002_0800_0815_mlat.ast", date="2020-10-02")
    assert mlat20.field_monitors == FIELD_MONITORS and len(np.unique(mlat20.key)) == 10


def test_mlat_tracks_against_adsb_2016(lebl, tmp_path, capsys):
    data, sites = lebl
    out = tmp_path / "mlat.json"
    code = main(["eval", "--sensor-tracks", str(data / "lebl_20160510_2200_2215_mlat.ast"),
                 "--reference", str(data / "lebl_20160510_2200_2215_adsb.ast"),
                 "--sites", str(sites), "--date", "2016-05-10",
                 "--reference-time-offset", "auto", "--json", str(out)])  # fmt: skip
    assert code == 0
    d = json.loads(out.read_text())
    r = d["reference"]
    assert d["sensor_tracks"]["sensors"] == ["0-107"]
    assert d["sensor_tracks"]["counts"]["field_monitor"] == 5220
    # MLAT positions ahead of ADS-B by ≈ 0.4 s airborne: the survey's +0.42 s (median)
    assert 0.3 < r["time_offset"]["lead_median_s"] < 0.55
    assert r["time_offset"]["applied_s"] == -r["time_offset"]["lead_median_s"]
    for phase in ("surface", "airborne"):
        p = r[phase]
        # the MLAT's addresses are the aircraft's own: every checked one is correct
        assert p["identity"]["mode_s"]["share"] == 1.0 and p["identity"]["mode_s"]["checked"]
        assert p["false_tracks"] == 0
    # on the ground the two agree to ≈ 6.5 m median (survey): an RMS of tens of metres
    assert 5.0 < r["surface"]["position"]["rms_m"] < 30.0
    assert r["surface"]["probability_of_update"] > 0.8
    assert "surface" in capsys.readouterr().out


def test_smr_tracks_against_mlat_2020(lebl, tmp_path):
    data, sites = lebl
    out = tmp_path / "smr.json"
    code = main(["eval", "--sensor-tracks", str(data / "lebl_20201002_0800_0815_smr.ast"),
                 "--reference", str(data / "lebl_20201002_0800_0815_mlat.ast"),
                 "--sites", str(sites), "--date", "2020-10-02", "--json", str(out)])  # fmt: skip
    assert code == 0
    r = json.loads(out.read_text())["reference"]
    s = r["surface"]
    # the SMR shows no identity; it sees vehicles the MLAT does not report
    assert s["identity"]["mode_s"]["checked"] == 0
    assert r["all"]["outside_reference_tracks"] > 0
    assert 0 < s["probability_of_update"] < 1 and s["position"]["rms_m"] < 30.0


def test_a_site_relative_reference_without_its_site_is_a_clear_error(lebl, caplog):
    data, _ = lebl
    code = main(["eval", "--sensor-tracks", str(data / "lebl_20201002_0800_0815_smr.ast"),
                 "--reference", str(data / "lebl_20201002_0800_0815_mlat.ast"),
                 "--date", "2020-10-02"])  # fmt: skip
    assert code == 1
    assert "no reference report could be placed: give --sites" in caplog.text


# ---- the command on a simulated recording ---------------------------------------------


def truth_as_adsb(recording, out, ground_targets=(0, 1, 2)) -> str:
    """The recording's Truth messages as CAT021 edition 2.6 records (one per target and
    message: I071 time, I131 position, I080 address 0x100000 + target id, I040 GBS for
    ``ground_targets``, I145 FL 10 for the others); returns the UTC date."""
    blocks, day = [], None
    for rec in iter_recording(recording):
        m = rec.message
        if not isinstance(m, Truth):
            continue
        day = day or np.datetime64(m.time, "ns").astype("datetime64[D]")
        tod = (m.time - day.astype("datetime64[ns]").astype(np.int64)) / 1e9
        for i, tid in enumerate(m.target_id):
            g = int(tid in ground_targets)
            items = {
                "010": (("SAC", 0), ("SIC", 1)),
                "040": ((0, 0, 0, 0, None), (0, g, 0, 0, 0, 0, None)),
                "071": round(tod * 128),
                "131": (
                    ("LAT", round(m.lat[i] / 180 * 2**30)),
                    ("LON", round(m.lon[i] / 180 * 2**30)),
                ),
                "080": 0x100000 + int(tid),
            }
            if not g:
                items["145"] = 40  # FL 10
            rec021 = gen.Cat_021_2_6.cv_record.create(items)
            blocks.append(gen.Cat_021_2_6.create([rec021]).unparse().to_bytes())
    out.write_bytes(b"".join(blocks))
    return str(day)


TRACKER = ["--tracker", "lmits", "--motion", "cv", "--depth", "3", "--q", "0.75"]


def test_eval_scores_the_tracker_against_the_truth_as_adsb(simulated_recording, tmp_path):
    rec = simulated_recording("--scenario", "thesis-mtt-5", "--seed", "2")
    ref = tmp_path / "truth_adsb.ast"
    date = truth_as_adsb(rec, ref)
    out = tmp_path / "eval.json"
    code = main(["eval", str(rec), *TRACKER, "--reference", str(ref),
                 "--reference-date", date, "--json", str(out)])  # fmt: skip
    assert code == 0
    d = json.loads(out.read_text())
    r = d["reference"]
    assert r["reference_file"]["aircraft"] == 5 and r["reference_file"]["reports"] == 205
    assert (r["surface"]["aircraft"], r["airborne"]["aircraft"]) == (3, 2)
    # 5 targets, σ 5 m cartesian sensor, 1 s scans: every target tracked once confirmed
    for phase in ("surface", "airborne"):
        p = r[phase]
        assert p["aircraft_tracked"] == p["aircraft"]
        assert 0.5 < p["probability_of_update"] <= 1.0
        assert 0 < p["position"]["rms_m"] < 15.0
        assert p["false_tracks"] == 0 and p["outside_reference_tracks"] == 0
    assert r["updates_credited"] <= r["updates"] and r["time_offset"]["applied_s"] == 0.0

    # the same tracks recorded by skyfuse track and scored from the recording: the same
    tracks = tmp_path / "tracks.mcap"
    assert main(["track", str(rec), *TRACKER, "--out", str(tracks)]) == 0
    out2 = tmp_path / "tracks.json"
    code = main(["eval", "--tracks", str(tracks), "--reference", str(ref),
                 "--reference-date", date, "--json", str(out2)])  # fmt: skip
    assert code == 0
    # the input bound needs the plots the tracker was given: the live run only
    live = _without_input(r)
    assert r["surface"]["input_windows"] >= r["surface"]["windows_updated"] * 0.5
    assert _without_input(json.loads(out2.read_text())["reference"]) == live


def _without_input(d):
    if isinstance(d, dict):
        return {k: _without_input(v) for k, v in d.items() if "input" not in k}
    return [_without_input(v) for v in d] if isinstance(d, list) else d


def test_eval_reference_command_line_errors(tmp_path, capsys):
    assert main(["eval", "--tracks", str(tmp_path / "t.mcap")]) == 2
    assert "give --reference FILE" in capsys.readouterr().err
    assert main(["eval"]) == 2
    assert "give a scenario" in capsys.readouterr().err
    code = main(["eval", "--tracks", str(tmp_path / "t.mcap"),
                 "--reference", str(tmp_path / "nope.ast")])  # fmt: skip
    assert code == 2 and "does not exist" in capsys.readouterr().err
    code = main(["eval", "crossing-4g", "--sensor-tracks", "x.ast", "--reference", "r.ast"])
    assert code == 2 and "give no scenario" in capsys.readouterr().err
