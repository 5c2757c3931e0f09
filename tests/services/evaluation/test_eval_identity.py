"""``skyfuse eval FILE`` scores the identity the tracks showed (observers.LabelObserver,
fusion/metrics/identity_metrics.py) on a simulated regional recording whose aircraft
reply with addresses, callsigns and flight levels, change codes and garble replies."""

from __future__ import annotations

import json

from skyfuse.services.cli.main import main

ARGS = ("--scenario", "regional", "--duration", "150", "--targets", "14", "--seed", "5",
        "--param", "ehs_fraction=0.5,code_change_fraction=0.3,garble_probability=0.05")  # fmt: skip


def test_eval_reports_the_identity_of_the_tracks(simulated_recording, tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["eval", str(simulated_recording(*ARGS)), "--json", str(out)]) == 0
    headline = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    d = json.loads(out.read_text())["identity"]
    assert d["mode_s_updates"] > 300 and d["mode_s_correct"] >= 0.98
    assert d["callsign_aircraft"] >= 5 and d["callsign_within_2_scans"] >= 0.8
    assert d["flight_level_updates"] > 300 and d["flight_level_within_1"] >= 0.9
    assert d["conflicts"] == len(d["conflict_list"]) and d["conflicts_per_hour"] >= 0
    for c in d["conflict_list"]:
        assert {"time_s", "utc", "track_id"} <= set(c) and ("mode_s" in c or "callsign" in c)
    assert headline["identity_mode_s_correct"] == d["mode_s_correct"]


def test_eval_without_identity_reports_none(simulated_recording, tmp_path):
    out = tmp_path / "r.json"
    rec = simulated_recording(*ARGS)
    assert main(["eval", str(rec), "--no-identity", "--json", str(out)]) == 0
    assert "identity" not in json.loads(out.read_text())
