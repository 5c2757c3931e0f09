"""Radar, ADS-B and multilateration fused: a synthetic scenario in which the fused tracks'
position error is below each sensor's alone, through the offline runner of ``skyfuse
track`` (``run_offline``: conversion, adapter, tracker).

Six aircraft fly straight at 3 km for 120 s within 20 km of the origin. The sensors'
error models are written here, independently of the conversion: a 2-D rotating radar
40 km south (4 s scans, σ 50 m in range and 1.5 mrad in azimuth, Mode-C heights), ADS-B
(1 s, σ 20 m east and north at the aircraft, two of the six aircraft not equipped) and a
multilateration (1 s, x/y east/north of its reference point, σ 15 m, P_D 0.9). Truth
positions go into the system frame through pymap3d and the frame's own geodesy (checked
against pyproj in ``test_frames``). Errors are taken after every batch at the batch
time, for the confirmed track nearest to each aircraft, after a 30 s settling time.
"""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.tracker import TrackerConfig
from skyfuse.schemas import PlotBatch, RadarKind, RadarSite
from skyfuse.services.evaluation.offline import Observer, OfflineConfig, Step, run_offline

LAT0, LON0 = 41.3, 2.1
T0 = 1_700_000_000 * 10**9
S = 10**9
DURATION = 120
N_AC = 6
EQUIPPED = np.array([True, True, True, True, False, False])  # ADS-B out
SIG_R, SIG_AZ, SIG_ADSB, SIG_MLAT = 50.0, 1.5e-3, 20.0, 15.0

RADAR = RadarSite(radar_id="R", lat=41.3 - 40e3 / 111e3, lon=LON0, alt=50.0,
                  kind=RadarKind.TWO_D, sigma_range=SIG_R, sigma_azimuth=SIG_AZ,
                  p_detection=0.9, max_range=200e3)  # fmt: skip
ADSB = RadarSite(radar_id="A-adsb", lat=LAT0, lon=LON0, alt=4.0, kind="wgs84",
                 detection="reports", report_timeout=5.0, sigma_cartesian=SIG_ADSB,
                 p_detection=0.95, max_range=250e3)  # fmt: skip
MLAT = RadarSite(radar_id="M", lat=LAT0 + 0.01, lon=LON0 + 0.02, alt=4.0,
                 kind=RadarKind.CARTESIAN, detection="reports", report_timeout=5.0,
                 sigma_cartesian=SIG_MLAT, p_detection=0.9, max_range=60e3)  # fmt: skip
SITES = {s.radar_id: s for s in (RADAR, ADSB, MLAT)}


def truth(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat, lon, h) of the aircraft (N_AC, len(t)): straight lines at 3 km in the ENU of
    the origin, 120-220 m/s in six directions."""
    rng = np.random.default_rng(7)
    p0 = rng.uniform(-12e3, 12e3, (N_AC, 2))
    course = np.arange(N_AC) * (2 * np.pi / N_AC) + 0.3
    speed = np.linspace(120.0, 220.0, N_AC)
    v = speed[:, None] * np.stack([np.sin(course), np.cos(course)], axis=1)
    e = p0[:, :1] + v[:, :1] * t_s[None, :]
    n = p0[:, 1:] + v[:, 1:] * t_s[None, :]
    return pymap3d.enu2geodetic(e, n, np.full_like(e, 3000.0), LAT0, LON0, 0.0)


def _batch(site, seq, t_lo, t_hi, times, **cols) -> PlotBatch:
    return PlotBatch(radar_id=site.radar_id, scan=seq, seq=seq, time_start=t_lo, time_end=t_hi,
                     time=[int(t) for t in times],
                     **{k: [float(x) for x in c] for k, c in cols.items()})  # fmt: skip


def radar_batches(rng) -> list[PlotBatch]:
    """One batch per 4-s scan; each aircraft seen (P_D 0.9) when the beam passes it."""
    out = []
    for k in range(DURATION // 4):
        t_lo = k * 4.0
        lat, lon, h = truth(np.array([t_lo + 2.0]))
        az, _, rng_m = pymap3d.geodetic2aer(lat[:, 0], lon[:, 0], h[:, 0], RADAR.lat,
                                            RADAR.lon, RADAR.alt)  # fmt: skip
        az = np.deg2rad(az)
        t = t_lo + 4.0 * az / (2 * np.pi)  # the beam's time at each aircraft
        lat, lon, h = (a[np.arange(N_AC), np.arange(N_AC)] for a in truth(t))
        az, _, rng_m = pymap3d.geodetic2aer(lat, lon, h, RADAR.lat, RADAR.lon, RADAR.alt)
        seen = rng.random(N_AC) < 0.9
        o = np.argsort(t[seen])
        azm = (np.deg2rad(az[seen]) + rng.normal(0, SIG_AZ, seen.sum())) % (2 * np.pi)
        out.append(_batch(RADAR, k, T0 + round(t_lo * S), T0 + round((t_lo + 4) * S),
                          T0 + np.round(t[seen][o] * S),
                          range=(rng_m[seen] + rng.normal(0, SIG_R, seen.sum()))[o],
                          azimuth=azm[o], altitude=h[seen][o]))  # fmt: skip
    return out


def report_batches(rng, site, sigma, who, p_d) -> list[PlotBatch]:
    """One batch a second of the reports of the aircraft ``who`` (P_D ``p_d``): noise
    N(0, σ²) east and north at the aircraft (ADS-B, as lat/lon) or on x/y of the
    reference point (multilateration)."""
    out = []
    for k in range(DURATION):
        t = k + 0.3 + 0.05 * np.arange(N_AC)
        lat, lon, h = (a[np.arange(N_AC), np.arange(N_AC)] for a in truth(t))
        e, n, _ = pymap3d.geodetic2enu(lat, lon, h, site.lat, site.lon, site.alt)
        sel = who & (rng.random(N_AC) < p_d)
        de, dn = rng.normal(0, sigma, (2, sel.sum()))
        times = T0 + np.round(t[sel] * S)
        span = (T0 + k * S, T0 + (k + 1) * S)
        if site.kind == "wgs84":
            la, lo, _ = pymap3d.enu2geodetic(de, dn, 0.0, lat[sel], lon[sel], h[sel])
            cols = {"lat": la, "lon": lo}
        else:
            cols = {"x": e[sel] + de, "y": n[sel] + dn}
        out.append(_batch(site, k, *span, times, altitude=h[sel], sigma=np.full(sel.sum(), sigma),
                          **cols))  # fmt: skip
    return out


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
    rng = np.random.default_rng(11)
    every = np.ones(N_AC, bool)
    return {
        "radar": radar_batches(rng),
        "adsb": report_batches(rng, ADSB, SIG_ADSB, EQUIPPED, 0.95),
        "mlat": report_batches(rng, MLAT, SIG_MLAT, every, 0.9),
    }


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
