"""Acceptance: ``skyfuse demo`` starts 3 sensors + fusion + recorder as real processes on
a free loopback port, runs a short accelerated regional scenario, and stops them cleanly;
most detectable targets get a confirmed track; every published plot batch is recorded."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from service_support import ROOT

pytestmark = pytest.mark.service


def test_demo_three_radars_end_to_end(tmp_path):
    out, js = tmp_path / "demo.mcap", tmp_path / "demo.json"
    cmd = [
        sys.executable, "-m", "skyfuse.services.cli", "demo", "--radars", "3", "--targets", "6",
        "--duration", "60", "--speed", "15", "--seed", "2", "--out", str(out),
        "--json", str(js), "--workdir", str(tmp_path), "--no-live",
    ]  # fmt: skip
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, timeout=120)
    log = res.stderr.decode(errors="replace")[-4000:]
    assert res.returncode == 0, log
    s = json.loads(js.read_text())
    assert s["failed_services"] == []
    for name, svc in s["services"].items():
        assert svc["exit_code"] == 0, (name, svc)
        if svc["stop_s"] is not None:  # sensors finish on their own; the rest get SIGTERM
            assert svc["stop_s"] < 5.0, (name, svc)
    assert s["radars"] == ["LRTR", "LYBE", "LYVR"]
    # no loss: every batch the sensors published was recorded and reached the fusion
    assert s["plot_batches_published"] > 100
    assert s["plot_batches_recorded"] == s["plot_batches_published"]
    assert s["fusion_batches_in"] == s["plot_batches_published"]
    assert s["fusion_plots_in"] == s["plots_recorded"]
    assert not s["recording_truncated"]
    # tracking: most targets the radars saw are confirmed; GOSPA well below c
    assert s["targets_detectable"] >= 3
    assert s["targets_confirmed"] >= 0.7 * s["targets_detectable"], s
    assert s["gospa_mean_second_half_m"] < s["gospa_c_m"]
    assert s["latency_ms"]["count"] == s["fusion_cycles"] > 0
    assert Path(s["png"]).stat().st_size > 10_000
    # identity: the tracks are listed by the callsigns the simulated aircraft downlinked
    assert any(line.startswith("  tracks by callsign") for line in res.stdout.decode().splitlines())
    sent = {c for b in recorded_plots(out) for c in b.callsign or () if c}
    listed = {name for name in s["tracks_by_callsign"] if not name.startswith("squawk ")}
    assert listed and listed <= sent, (listed, sent)
    assert len(listed) >= 0.7 * len(sent)


def recorded_plots(path: Path):
    from skyfuse.schemas import PlotBatch
    from skyfuse.services.recording.mcap_io import iter_recording

    return [r.message for r in iter_recording(path) if isinstance(r.message, PlotBatch)]
