"""The particle tracker on multi-radar polar plots: the product's sample recording
(``recordings/regional-demo.mcap``: three rotating radars, 2-D and 3-D, polar plots with
simulation truth) through ``skyfuse track --tracker lmipf`` — the live service's pipeline
(conversion into the stereographic system plane with each plot's own covariance, sector
coverage, cross-radar ordering). Reference: the default LM-ITS N = 3 on the same file."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from skyfuse.services.cli.main import main

RECORDING = Path(__file__).resolve().parents[2] / "recordings" / "regional-demo.mcap"


def track_summary(tmp_path: Path, *args: str) -> dict:
    out = tmp_path / f"{'-'.join(args)}.json"
    assert main(["track", str(RECORDING), *args, "--json", str(out)]) == 0
    return json.loads(out.read_text())


@pytest.mark.skipif(not RECORDING.exists(), reason="sample recording not in the tree")
def test_lmipf_on_polar_multiradar_recording_as_lmits(tmp_path):
    ref = track_summary(tmp_path, "--tracker", "lmits")
    pf = track_summary(tmp_path, "--tracker", "lmipf", "--particles", "300")
    assert pf["plots_processed"] == ref["plots_processed"] > 1000
    lab, lab_ref = pf["labels"], ref["labels"]
    assert lab["aircraft_with_confirmed_track"] == lab["aircraft"] >= 10
    assert lab["confirmed_false_tracks"] <= lab_ref["confirmed_false_tracks"]
    assert pf["truth"]["coverage_after_acquisition"] >= 0.95
    assert pf["truth"]["position_rmse_m"] < 1.3 * ref["truth"]["position_rmse_m"]
