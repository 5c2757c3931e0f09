"""The offline runner and its observers: truth scores of recorded tracks against closed
forms (GOSPA of one target and one track: localisation only, or one missed plus one
false), the coverage rule, and a tracked simulation written through TrackWriter."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.frames import SystemFrame
from skyfuse.schemas import FrameSpec, PlotBatch, Track, TrackBatch, TrackStatus, Truth
from skyfuse.services.evaluation.observers import Coverage, Timing, TrackWriter, TruthObserver
from skyfuse.services.evaluation.offline import OfflineConfig, run_offline
from skyfuse.services.fusion.system_frame import frame_for_sites

T0 = 1_700_000_000 * 10**9
S = 10**9
FRAME = FrameSpec(kind="stereographic", lat0=45.0, lon0=20.0)


def plots(k: int, target: int) -> PlotBatch:
    t = T0 + k * 4 * S
    return PlotBatch(
        radar_id="r", scan=k, seq=k, time_start=t - S, time_end=t, time=[t], range=[1e4],
        azimuth=[0.0], target_id=[target],
    )  # fmt: skip


def tracks(k: int, x: float, y: float) -> TrackBatch:
    t = T0 + k * 4 * S
    state = [x, 0.0, y, 0.0]
    trk = Track(
        track_id=7, time=t, status=TrackStatus.CONFIRMED, existence=0.99, state=state,
        covariance=np.eye(4).tolist(), lat=45.0, lon=20.0, vel_east=0.0, vel_north=0.0,
        speed=0.0, heading=0.0,
    )  # fmt: skip
    return TrackBatch(
        fusion_id="main", cycle=k, time=t, frame=FRAME, state_labels=["x", "vx", "y", "vy"],
        tracks=[trk],
    )  # fmt: skip


def truth(k: int, x: float, y: float) -> Truth:
    lat, lon, alt = SystemFrame.from_spec(FRAME).to_geodetic(
        np.array([x]), np.array([y]), np.array([0.0])
    )
    return Truth(time=T0 + k * 4 * S, target_id=[3], lat=lat.tolist(), lon=lon.tolist(),
                 alt=alt.tolist(), vel_east=[0.0], vel_north=[0.0], vel_up=[0.0])  # fmt: skip


def scenario(offset: tuple[float, float]) -> list:
    msgs = []
    for k in range(6):
        msgs += [plots(k, 3), tracks(k, 1000 + offset[0], 2000 + offset[1]), truth(k, 1000, 2000)]
    return msgs


def test_recorded_tracks_localisation_only_gospa_and_coverage():
    obs = TruthObserver(Coverage(window_s=15.0, min_detections=3), c=500.0)
    res = run_offline(scenario((30.0, 40.0)), None, OfflineConfig(tracker=None), [obs])
    assert res.frame.spec() == FRAME and res.counts["track batches"] == 6
    s = res.summary()["truth"]
    # in coverage from the 3rd detection (k = 2): 4 samples of the target, all within c
    assert s["target_samples_in_coverage"] == 4 and s["coverage"] == 1.0
    assert s["position_rmse_m"] == pytest.approx(50.0, abs=1e-3)
    assert s["targets_confirmed"] == s["targets_detectable"] == 1
    # before coverage: no truth, one false track: (c^p/2)^(1/p); after: the 50 m error
    g = s["gospa"]
    false_only = 500.0 / 2**0.5
    assert g["mean_m"] == pytest.approx((2 * false_only + 4 * 50.0) / 6, abs=0.01)
    assert g["final_m"] == pytest.approx(50.0, abs=1e-3)


def test_recorded_track_beyond_cutoff_is_one_missed_and_one_false():
    obs = TruthObserver(Coverage(min_detections=1), c=500.0)
    res = run_offline(scenario((600.0, 0.0)), None, OfflineConfig(tracker=None), [obs])
    s = res.summary()["truth"]
    assert s["coverage"] == 0.0 and s["position_rmse_m"] is None
    # one missed + one false: (c^p/2 + c^p/2)^(1/p) = c
    assert s["gospa"]["final_m"] == pytest.approx(500.0) and s["gospa"]["final_missed"] == 1


def test_coverage_rule_needs_detections_within_the_window():
    cov = Coverage(window_s=10.0, min_detections=2)
    cov.add(plots(0, 3))
    assert not cov.inside(T0, [3]).any()  # one detection only
    cov.add(plots(1, 3))
    assert cov.inside(T0 + 4 * S + 10 * S, [3, 9]).tolist() == [True, False]
    assert not cov.inside(T0 + 4 * S + 11 * S, [3]).any()  # last plot 11 s ago


def test_tracked_simulation_fixes_the_frame_by_the_rule_and_writes_every_step(tmp_path):
    from skyfuse.fusion.sim import Simulator, build_scenario
    from skyfuse.fusion.tracker import TrackerConfig
    from skyfuse.services.recording.mcap_io import RecordingWriter, iter_recording

    sim = Simulator(build_scenario("regional", seed=3, duration=12.0, targets=3, radars=3))
    msgs = [ev.message for ev in sim.run(truth=True)]
    sites = [m for m in msgs if type(m).__name__ == "RadarSite"]
    n = sum(isinstance(m, PlotBatch) for m in msgs)
    out = tmp_path / "t.mcap"
    with RecordingWriter(out) as w:
        observers = [TrackWriter(w), Timing()]
        res = run_offline(msgs, None, OfflineConfig(tracker=TrackerConfig()), observers)
    assert res.frame.spec() == frame_for_sites(sites) and res.counts["batches"] == n > 10
    written = [r.message for r in iter_recording(out) if isinstance(r.message, TrackBatch)]
    assert len(written) == n and all(b.frame == res.frame.spec() for b in written)
    assert res.summary()["timing"]["ms_per_batch_mean"] > 0


def test_timing_stops_at_the_last_step_not_at_the_summary():
    """The offline rate is the run's: work after the last step (the truth scoring of the
    summaries) is not in it; the steps' own rate is reported beside it."""
    import time
    from types import SimpleNamespace

    t = Timing()
    for _ in range(3):
        t.on_step(SimpleNamespace(ms=10.0, batch=[0] * 50))
    time.sleep(0.3)  # a slow summary of another observer
    got = t.summary()["timing"]
    assert got["wall_s"] < 0.2
    assert got["plots_per_s_steps"] == pytest.approx(5000.0)
    assert got["plots_per_s"] >= 150 / 0.2
