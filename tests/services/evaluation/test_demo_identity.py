"""The demo report lists the confirmed tracks by callsign (or squawk) when the recorded
tracks carry identities, and is unchanged when they do not."""

from __future__ import annotations

import numpy as np
from service_support import EPOCH, make_batch, make_site
from skyfuse.schemas import TrackBatch, Truth, keys
from skyfuse.services.evaluation.demo import identity_lines, report_recording
from skyfuse.services.recording.mcap_io import RecordingWriter


def _track(i: int, t: int, status: str = "confirmed", **identity) -> dict:
    return {
        "track_id": i, "time": t, "status": status, "existence": 0.9, "state": [0.0] * 4,
        "covariance": [[float(r == c) for c in range(4)] for r in range(4)], "lat": 45.0,
        "lon": 20.0, "vel_east": 0.0, "vel_north": 100.0, "speed": 100.0, "heading": 0.0,
        **identity,
    }  # fmt: skip


def _recording(path, tracks_per_cycle) -> None:
    rng = np.random.default_rng(0)
    with RecordingWriter(path, metadata={"command": "test"}) as w:
        w.write(keys.radar_site("R1"), make_site("R1", 45.0, 20.0), EPOCH)
        for k, tracks in enumerate(tracks_per_cycle):
            b = make_batch("R1", k, 0, 1, 2, rng)
            w.write(keys.radar_plots("R1"), b, b.time_end)
            t = b.time_end
            tb = TrackBatch(fusion_id="main", cycle=k + 1, time=t, kind="full",
                            frame={"kind": "stereographic", "lat0": 45.0, "lon0": 20.0},
                            state_labels=["x", "vx", "y", "vy"],
                            tracks=[_track(i, t, **kw) for i, kw in tracks])  # fmt: skip
            w.write(keys.fusion_tracks("main"), tb, t)
            w.write(keys.SIM_TRUTH, Truth(time=t, target_id=[1], lat=[45.0], lon=[20.0],
                                          alt=[9000.0], vel_east=[0.0], vel_north=[100.0],
                                          vel_up=[0.0]), t)  # fmt: skip


def test_tracks_are_listed_by_callsign_or_squawk(tmp_path):
    path = tmp_path / "demo.mcap"
    _recording(path, [
        [(1, {"callsign": "JAT123"}), (2, {"mode_3a": 0o4004}), (9, {"status": "tentative",
                                                                      "callsign": "LOT9"})],
        [(3, {"callsign": "JAT123"}), (2, {"mode_3a": 0o4004}), (4, {})],
    ])  # fmt: skip
    s = report_recording(path).summary
    assert s["tracks_by_callsign"] == {"JAT123": [1, 3], "squawk 4004": [2]}
    (line,) = identity_lines(s)
    assert "JAT123 1/3" in line and "squawk 4004 2" in line and "LOT9" not in line


def test_without_identities_the_report_has_no_listing(tmp_path):
    path = tmp_path / "demo.mcap"
    _recording(path, [[(1, {}), (2, {})], [(1, {})]])
    s = report_recording(path).summary
    assert "tracks_by_callsign" not in s and identity_lines(s) == []
    assert s["confirmed_track_ids"] == 2
