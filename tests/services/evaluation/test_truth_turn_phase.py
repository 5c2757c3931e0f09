"""The truth observer's RMSE split into turn and straight flight: a target that flies
straight, then turns at 0.05 rad/s (2.9 °/s), scored against a track with a known error in
each phase (closed form: the RMSE of each phase is that phase's error)."""

from __future__ import annotations

import numpy as np
import pytest
from skyfuse.fusion.frames import SystemFrame
from skyfuse.schemas import FrameSpec, PlotBatch, Track, TrackBatch, TrackStatus, Truth
from skyfuse.services.evaluation.observers import Coverage, TruthObserver
from skyfuse.services.evaluation.offline import OfflineConfig, run_offline

T0, S = 1_700_000_000 * 10**9, 10**9
FRAME = FrameSpec(kind="stereographic", lat0=45.0, lon0=20.0)
OMEGA, TURN_FROM = 0.05, 5  # rad/s; first scan whose heading differs from the previous one


def _messages(err_straight: float, err_turn: float) -> list:
    geo = SystemFrame.from_spec(FRAME)
    lat, lon, alt = (a.tolist() for a in geo.to_geodetic(*np.array([[1e3], [2e3], [0.0]])))
    msgs = []
    for k in range(10):
        t = T0 + 4 * k * S
        heading = OMEGA * 4.0 * max(0, k - TURN_FROM + 1)
        ve, vn = 200.0 * np.cos(heading), 200.0 * np.sin(heading)
        dx = err_turn if k >= TURN_FROM else err_straight
        trk = Track(
            track_id=7,
            time=t,
            status=TrackStatus.CONFIRMED,
            existence=0.99,
            state=[1e3 + dx, 0.0, 2e3, 0.0],
            covariance=np.eye(4).tolist(),
            lat=45.0,
            lon=20.0,
            vel_east=0.0,
            vel_north=0.0,
            speed=0.0,
            heading=0.0,
        )
        msgs += [
            PlotBatch(radar_id="r", scan=k, seq=k, time_start=t - S, time_end=t, time=[t],
                      range=[1e4], azimuth=[0.0], target_id=[3]),
            TrackBatch(fusion_id="main", cycle=k, time=t, frame=FRAME,
                       state_labels=["x", "vx", "y", "vy"], tracks=[trk]),
            Truth(time=t, target_id=[3], lat=lat, lon=lon, alt=alt, vel_east=[ve],
                  vel_north=[vn], vel_up=[0.0]),
        ]  # fmt: skip
    return msgs


def test_rmse_split_by_truth_turn_rate():
    obs = TruthObserver(Coverage(min_detections=1), c=500.0)
    run_offline(_messages(30.0, 120.0), None, OfflineConfig(tracker=None), [obs])
    s = obs.summary()["truth"]
    phase = s["position_rmse_by_phase"]
    assert phase["turn"]["samples"] == 10 - TURN_FROM
    assert phase["straight"]["samples"] == TURN_FROM
    assert phase["turn"]["rmse_m"] == pytest.approx(120.0, abs=1e-3)
    assert phase["straight"]["rmse_m"] == pytest.approx(30.0, abs=1e-3)
    overall = np.sqrt((TURN_FROM * 30.0**2 + (10 - TURN_FROM) * 120.0**2) / 10)
    assert s["position_rmse_m"] == pytest.approx(overall, abs=0.1)
