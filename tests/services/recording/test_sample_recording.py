"""The shipped sample recording (made by `skyfuse demo`) is what the README's replay and
offline examples use: it must stay readable, complete and trackable."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from service_support import ROOT
from skyfuse.services.cli.cmd_inspect import inspect_recording

SAMPLE = ROOT / "recordings" / "regional-demo.mcap"


def test_sample_is_small_complete_and_valid():
    assert SAMPLE.stat().st_size < 2 * 1024 * 1024
    info = inspect_recording(SAMPLE)
    assert not info["truncated"] and info["rejected"] == {}
    radars = [r for r in info["radars"] if r["plots"] > 0]
    assert len(radars) >= 3 and all(r["site"] for r in radars)
    assert info["targets"] >= 10 and info["truth_messages"] > 0
    assert info["confirmed_tracks"] > 0
    assert info["metadata"], "the recording carries its metadata"


@pytest.mark.parametrize("tracker", ["lmits", "ipda"])
def test_offline_tracking_of_the_sample(tmp_path, tracker):
    out, js = tmp_path / "t.mcap", tmp_path / "t.json"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "skyfuse.services.cli",
            "track",
            str(SAMPLE),
            "--tracker",
            tracker,
            "--depth",
            "3",
            "--out",
            str(out),
            "--json",
            str(js),
            "--no-progress",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads(js.read_text())
    assert summary["plots_processed"] > 3000
    assert summary["labels"]["aircraft_with_confirmed_track"] >= 10
    assert summary["labels"]["confirmed_false_tracks"] <= 2
    tracked = inspect_recording(out)
    assert tracked["confirmed_tracks"] >= 8
