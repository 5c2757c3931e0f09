"""Plots without a flight level are converted at the radar site's height (± 3000 m) by
default, live and offline: checked against the closed-form ground range of
a plot on the slant-range sphere (pymap3d for the geodesy)."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
from skyfuse.fusion.frames import SystemFrame
from skyfuse.schemas import FrameKind, FrameSpec, PlotBatch, RadarKind, RadarSite
from skyfuse.services.fusion.pipeline import TrackPipeline

T0 = 1_700_000_000_000_000_000


def _site() -> RadarSite:
    return RadarSite(radar_id="R1", lat=41.3, lon=2.1, alt=27.0, kind=RadarKind.TWO_D,
                     sigma_range=30.0, sigma_azimuth=math.radians(0.05))  # fmt: skip


def _batch(ranges, azimuths) -> PlotBatch:
    n = len(ranges)
    return PlotBatch(radar_id="R1", scan=0, seq=0, sector_start=0.0, sector_width=2 * math.pi,
                     time_start=T0, time_end=T0 + 4_000_000_000, time=[T0 + 1] * n,
                     range=list(ranges), azimuth=list(azimuths), altitude=[None] * n)  # fmt: skip


def _ground_ranges(pipe: TrackPipeline, site: RadarSite, batch: PlotBatch) -> np.ndarray:
    z = pipe.step(site, batch).batch.z
    assert len(z) == len(batch)  # nothing rejected
    # the plane position → latitude/longitude → local ENU of the site (pymap3d)
    lat, lon, _ = pipe.frame.to_geodetic(z[:, 0], z[:, 1], np.zeros(len(z)))
    e, n, _ = pymap3d.geodetic2enu(lat, lon, site.alt, site.lat, site.lon, site.alt)
    return np.hypot(e, n)


def test_plots_without_altitude_sit_at_the_site_height_by_default():
    site = _site()
    frame = SystemFrame.from_spec(FrameSpec(kind=FrameKind.STEREOGRAPHIC, lat0=41.3, lon0=2.1))
    D = np.array([3_000.0, 20_000.0, 60_000.0])
    psi = np.radians([10.0, 100.0, 250.0])
    rho_default = _ground_ranges(TrackPipeline(frame), site, _batch(D, psi))
    # closed form on a sphere of radius R: a point h above the antenna's height at
    # horizontal distance ρ is u ≈ h − ρ²/2R up in the site's ENU, so ρ = √(D² − u²);
    # at the site's own height (h = 0) ρ ≈ D
    R = 6_371_000.0
    u0 = -(D**2) / (2 * R)
    np.testing.assert_allclose(rho_default, np.sqrt(D**2 - u0**2), rtol=0, atol=15.0)
    # an explicit 3000 m instead: the height eats into the ground range
    rho_3000 = _ground_ranges(TrackPipeline(frame, assumed_altitude=3000.0), site,
                              _batch(D[1:], psi[1:]))  # fmt: skip
    u = 3000.0 - site.alt - D[1:] ** 2 / (2 * R)
    np.testing.assert_allclose(rho_3000, np.sqrt(D[1:] ** 2 - u**2), rtol=0, atol=30.0)
    assert (rho_default[1:] - rho_3000 > 50.0).all()  # 227 m at 20 km, 88 m at 60 km


def test_near_radar_plots_are_kept_and_counted():
    """A flight level above the slant range (3000 m at 1 km: |sin e| > 1) is kept, placed
    within the slant range of the radar (the site is the frame origin) and counted in
    ``plots_near_radar``; consistent plots (2 km up at 3 km, 3 km up at 50 km) are not."""
    site = _site()
    frame = SystemFrame.from_spec(FrameSpec(kind=FrameKind.STEREOGRAPHIC, lat0=41.3, lon0=2.1))
    pipe = TrackPipeline(frame)
    b = _batch([1_000.0, 3_000.0, 50_000.0], np.radians([0.0, 90.0, 180.0]))
    b = b.model_copy(update={"altitude": [3_000.0, 2_027.0, 3_000.0]})
    out = pipe.step(site, b)
    assert len(out.batch.z) == 3 and not pipe.rejected
    assert pipe.registration.plots_near_radar == 1
    assert np.hypot(*out.batch.z[0]) <= 1_000.0 + 1.0  # within D of the radar
