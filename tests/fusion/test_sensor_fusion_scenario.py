"""Radar, ADS-B and multilateration fused: a synthetic scenario in which the fused tracks'
position error is below each sensor's alone, through the offline runner of ``skyfuse
track`` (``run_offline``: conversion, adapter, tracker).

Six aircraft fly straight at 3 km for 120 s within 20 km of the origin. The scenario
simulator (``fusion.sim``, whose error models are checked against Monte Carlo runs in
``test_sim_radar`` and ``test_sim_report_sensors``) makes the sensors' data: a 2-D
rotating radar 40 km south (4 s scans, σ 50 m in range and 1.5 mrad in azimuth, Mode-C
heights), ADS-B (1 s, NACp 9: σ 12.3 m east and north at the aircraft, two of the six
aircraft without a Mode-S address, so not equipped) and a multilateration (1 s, x/y
east/north of its reference point, σ 15 m, P_D 0.9). Truth positions go into the system
frame through the frame's own geodesy (checked against pyproj in ``test_frames``).
Errors are taken after every batch at the batch time, for the confirmed track nearest to
each aircraft, after a 30 s settling time.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from skyfuse.fusion.frames import Stereographic, SystemFrame
from skyfuse.fusion.sim import Scenario, SensorConfig, Simulator, TargetSet, TrajectoryBuilder
from skyfuse.fusion.sim.sensor import ReportModel
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.schemas import FrameKind, FrameSpec, PlotBatch, RadarKind, RadarSite
from skyfuse.services.evaluation.offline import Observer, OfflineConfig, Step, run_offline

LAT0, LON0 = 41.3, 2.1
T0 = 1_700_000_000 * 10**9
S = 10**9
DURATION = 120
N_AC = 6
EQUIPPED = np.array([True, True, True, True, False, False])  # ADS-B out
SIG_R, SIG_AZ, SIG_MLAT = 50.0, 1.5e-3, 15.0

RADAR = RadarSite(radar_id="R", lat=41.3 - 40e3 / 111e3, lon=LON0, alt=50.0,
                  kind=RadarKind.TWO_D, sigma_range=SIG_R, sigma_azimuth=SIG_AZ,
                  p_detection=0.9, max_range=200e3)  # fmt: skip
ADSB = RadarSite(radar_id="A-adsb", lat=LAT0, lon=LON0, alt=4.0, kind="wgs84",
                 detection="reports", report_timeout=5.0, sigma_cartesian=20.0,
                 scan_period=1.0, p_detection=0.95, max_range=250e3, n_sectors=1,
                 timing="plots")  # fmt: skip
MLAT = RadarSite(radar_id="M", lat=LAT0 + 0.01, lon=LON0 + 0.02, alt=4.0,
                 kind=RadarKind.CARTESIAN, detection="reports", report_timeout=5.0,
                 sigma_cartesian=SIG_MLAT, scan_period=1.0, p_detection=0.9, max_range=60e3,
                 n_sectors=1, timing="plots")  # fmt: skip
SITES = {s.radar_id: s for s in (RADAR, ADSB, MLAT)}
PLANE = Stereographic(LAT0, LON0)


@functools.cache
def scenario() -> Scenario:
    """Straight lines at 3 km in the system plane, 120-220 m/s in six directions; every
    aircraft has a Mode-3/A code (the multilateration locates it), the equipped ones a
    Mode-S address."""
    rng = np.random.default_rng(7)
    p0 = rng.uniform(-12e3, 12e3, (N_AC, 2))
    course = np.arange(N_AC) * (2 * np.pi / N_AC) + 0.3
    speed = np.linspace(120.0, 220.0, N_AC)
    v = speed[:, None] * np.stack([np.sin(course), np.cos(course)], axis=1)
    builders = [TrajectoryBuilder(0.0, (*p0[i], 3000.0), (*v[i], 0.0)) for i in range(N_AC)]
    targets = TargetSet.from_builders(
        builders, mode_s=np.where(EQUIPPED, 0x3C0000 + np.arange(N_AC), -1),
        mode_3a=0o1000 + np.arange(N_AC),
    )  # fmt: skip
    sensors = [SensorConfig(site=RADAR),
               SensorConfig(site=ADSB, report=ReportModel(equipped_fraction=1.0, nacp=9)),
               SensorConfig(site=MLAT)]  # fmt: skip
    return Scenario(
        name="radar-adsb-mlat", description="", sites=[c.site for c in sensors],
        frame=FrameSpec(kind=FrameKind.STEREOGRAPHIC, lat0=LAT0, lon0=LON0),
        duration=float(DURATION), start_time=T0, n_targets=N_AC, params={}, targets=targets,
        sensors=sensors, plane=PLANE, truth_period=1.0, seed=11,
    )  # fmt: skip


def truth(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat, lon, h) of the aircraft (N_AC, len(t))."""
    idx = np.broadcast_to(np.arange(N_AC)[:, None], (N_AC, len(t_s)))
    p, _ = scenario().targets.state(np.broadcast_to(t_s, idx.shape), idx)
    lat, lon = PLANE.inverse(p[..., 0], p[..., 1])
    return np.asarray(lat), np.asarray(lon), p[..., 2]


class Errors(Observer):
    """Horizontal error of the confirmed track nearest to each aircraft, after every batch
    from 30 s on (None when no confirmed track is within 500 m)."""

    def __init__(self, frame: SystemFrame) -> None:
        self.frame, self.rows = frame, []

    def on_step(self, step: Step) -> None:
        out = step.out
        t = (out.time_ns - T0) / S
        if t < 30.0:
            return
        lat, lon, h = truth(np.array([t]))
        x, y, _ = self.frame.from_geodetic(lat[:, 0], lon[:, 0], h[:, 0])
        pos = out.states[out.confirmed][:, [0, 2]]
        for i in range(N_AC):
            d = np.hypot(pos[:, 0] - x[i], pos[:, 1] - y[i]) if len(pos) else np.array([])
            self.rows.append((i, float(d.min()) if len(d) and d.min() < 500 else None))

    def rms(self, aircraft) -> tuple[float, float]:
        """(RMS m, share of (aircraft, batch) rows with a track) over ``aircraft``."""
        r = [e for i, e in self.rows if i in aircraft]
        e = np.array([x for x in r if x is not None])
        return float(np.sqrt(np.mean(e**2))), len(e) / len(r)


def run(batches) -> Errors:
    batches = sorted(batches, key=lambda b: b.time_end)
    cfg = OfflineConfig(tracker=TrackerConfig(motion="cv", q=1.0), frame_lat0=LAT0,
                        frame_lon0=LON0)  # fmt: skip
    obs = Errors(SystemFrame.stereographic(LAT0, LON0))
    run_offline(batches, dict(SITES), cfg, [obs])
    return obs


@pytest.fixture(scope="module")
def sensors():
    sim = Simulator(scenario())
    names = {"R": "radar", "A-adsb": "adsb", "M": "mlat"}
    out = {name: [] for name in names.values()}
    for ev in sim.run(truth=False):
        if isinstance(ev.message, PlotBatch):
            out[names[ev.message.radar_id]].append(ev.message)
    return out


def test_fused_error_is_below_each_sensor_alone(sensors):
    fused = run([b for bs in sensors.values() for b in bs])
    everyone, equipped = set(range(N_AC)), set(np.flatnonzero(EQUIPPED).tolist())
    for name, seen in (("radar", everyone), ("adsb", equipped), ("mlat", everyone)):
        alone_rms, alone_share = run(sensors[name]).rms(seen)
        fused_rms, fused_share = fused.rms(seen)
        assert alone_share > 0.9 and fused_share > 0.97, (name, alone_share, fused_share)
        assert fused_rms < alone_rms, (name, fused_rms, alone_rms)
    # the aircraft without ADS-B are tracked by the radar and the MLAT all the same
    rms, share = fused.rms(everyone - equipped)
    assert share > 0.97 and rms < run(sensors["radar"]).rms(everyone - equipped)[0]
