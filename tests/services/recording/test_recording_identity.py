"""Secondary-surveillance plot columns travel unchanged: simulator → ``skyfuse simulate``
MCAP → ``skyfuse replay`` payloads, and → CAT048 (``simulate --format asterix``) → read
back."""

from __future__ import annotations

import datetime as dt
from collections import Counter

from skyfuse.fusion.sim import Simulator, build_scenario
from skyfuse.schemas import PlotBatch
from skyfuse.schemas.plots import IDENTITY_COLUMNS
from skyfuse.services.recording.mcap_io import iter_recording
from skyfuse.services.sensors import replay as replay_mod

ARGS = ("--scenario", "regional", "--duration", "40", "--targets", "12", "--seed", "3",
        "--param", "ehs_fraction=1,code_change_fraction=0.5,garble_probability=0.05")  # fmt: skip


def _simulated() -> list[PlotBatch]:
    sc = build_scenario("regional", seed=3, duration=40.0, targets=12, ehs_fraction=1.0,
                        code_change_fraction=0.5, garble_probability=0.05)  # fmt: skip
    return [e.message for e in Simulator(sc).run() if e.kind == "plots"]


def test_identity_columns_survive_the_recording_and_the_replay(simulated_recording, monkeypatch):
    path = simulated_recording(*ARGS)
    recorded = [r.message for r in iter_recording(path) if isinstance(r.message, PlotBatch)]
    sent = _simulated()
    assert recorded == sent
    carried = {c for b in recorded for c in IDENTITY_COLUMNS if getattr(b, c) is not None}
    assert {"callsign", "flight_level", "mode_3a_garbled", "ground_speed"} <= carried
    assert any(c for b in recorded for c in (b.callsign or []))

    published = []

    class Pub:
        matching_status = type("M", (), {"matching": True})()

        def __init__(self, topic):
            self.topic = topic

        def put(self, data, attachment=None):
            published.append((self.topic, bytes(data)))

        def undeclare(self):
            pass

    monkeypatch.setattr(replay_mod, "declare_publisher", lambda s, topic: Pub(topic))
    monkeypatch.setattr(replay_mod, "declare_liveliness", lambda s, key: Pub(key))
    replay_mod.replay(None, path, fast=True)
    replayed = [PlotBatch.from_json_bytes(d) for t, d in published if t.endswith("/plots")]
    assert replayed == recorded


def test_identity_columns_through_simulate_asterix(tmp_path):
    from skyfuse.services.asterix import load_sites, read_asterix
    from skyfuse.services.cli.main import main

    out = tmp_path / "sim.ast"
    assert main(["simulate", *ARGS, "--format", "asterix", "--out", str(out), "--no-progress"]) == 0
    sites = load_sites(f"{out}.sites.toml")
    result = read_asterix(out, sites=sites, date=dt.date(2026, 1, 1))
    got = Counter(cs for b in result.batches for cs in b.callsign or [] if cs)
    sent = Counter(cs for b in _simulated() for cs in b.callsign or [] if cs)
    assert got == sent and len(got) >= 5  # every reply of every aircraft
    ehs = sum(v is not None for b in result.batches for v in (b.ground_speed or []))
    assert ehs > 50 and result.stats.get("cat048_bds_decoded_5_0", 0) > 50
