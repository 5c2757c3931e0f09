"""The plot conversion's side of registration: the bias correction inverts
the simulator's bias model exactly (pymap3d truth), and the returned sensitivity
∂z/∂(D, ψ) matches central finite differences of the conversion itself."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.fusion.frames.sensor_bias import SensorBias
from skyfuse.schemas import PlotBatch, RadarSite

SITES = [
    RadarSite(radar_id="r2", lat=45.15, lon=21.31, alt=104.0, kind="2d"),
    RadarSite(radar_id="r3", lat=44.82, lon=20.31, alt=122.0, kind="3d"),
]
BIAS = SensorBias(azimuth=math.radians(0.2), range=150.0, range_gain=200e-6, time=0.05)


def _targets(site, n=40, seed=0):
    rng = np.random.default_rng(seed)
    r = rng.uniform(20e3, 150e3, n)
    az = rng.uniform(0, 360, n)
    e, nn = r * np.sin(np.radians(az)), r * np.cos(np.radians(az))
    lat, lon, _ = pymap3d.enu2geodetic(e, nn, 0.0, site.lat, site.lon, site.alt)
    alt = rng.uniform(2000.0, 11000.0, n)
    a, el, sr = pymap3d.geodetic2aer(lat, lon, alt, site.lat, site.lon, site.alt)
    return lat, lon, alt, sr, np.radians(a), np.radians(el)


def _batch(site, D, psi, el, alt, t):
    third = {"elevation": el.tolist()} if site.kind == "3d" else {"altitude": alt.tolist()}
    return PlotBatch(radar_id=site.radar_id, scan=0, seq=0, time_start=int(t.min()),
                     time_end=int(t.max()), time=t.tolist(), range=D.tolist(),
                     azimuth=np.mod(psi, 2 * np.pi).tolist(), **third)  # fmt: skip


@pytest.mark.parametrize("site", SITES, ids=["2d", "3d"])
def test_correction_inverts_the_bias_model(site):
    frame = SystemFrame.stereographic(45.2, 20.8)
    lat, lon, alt, D, psi, el = _targets(site)
    t = 10**18 + np.arange(len(D), dtype=np.int64) * 10**6
    Db, pb, tb = BIAS.distort(D, psi, t)
    c = convert_plots(frame, site, _batch(site, Db, pb, el, alt, tb), bias=BIAS)
    ref = np.stack(frame.from_geodetic(lat, lon, alt), -1)[:, :2]
    assert c.valid.all() and c.bias is BIAS
    assert np.abs(c.z - ref).max() < 0.05  # metres, noise-free
    np.testing.assert_array_equal(c.time, t)
    raw = convert_plots(frame, site, _batch(site, Db, pb, el, alt, tb))
    # uncorrected: off by ≈ 150 m + 200 ppm in range and 0.2° × range across
    assert np.abs(raw.z - ref).max() > 150.0


@pytest.mark.parametrize("site", SITES, ids=["2d", "3d"])
def test_polar_jacobian_matches_finite_differences(site):
    frame = SystemFrame.stereographic(45.2, 20.8)
    _, _, alt, D, psi, el = _targets(site, n=10, seed=1)
    t = np.zeros(len(D), np.int64)
    c = convert_plots(frame, site, _batch(site, D, psi, el, alt, t))
    for col, (dD, dpsi) in enumerate([(1.0, 0.0), (0.0, 1e-6)]):
        hi = convert_plots(frame, site, _batch(site, D + dD, psi + dpsi, el, alt, t)).z
        lo = convert_plots(frame, site, _batch(site, D - dD, psi - dpsi, el, alt, t)).z
        fd = (hi - lo) / (2 * (dD + dpsi))
        np.testing.assert_allclose(c.polar_jacobian[:, :, col], fd, rtol=1e-4, atol=1e-4)


def test_cartesian_sensor_refuses_a_bias_and_debias_handles_near_radar_plots():
    frame = SystemFrame.planar()
    cart = RadarSite(radar_id="c", lat=0.0, lon=0.0, kind="cartesian")
    b = PlotBatch(radar_id="c", scan=0, seq=0, time_start=0, time_end=0, time=[0],
                  x=[1.0], y=[2.0])  # fmt: skip
    with pytest.raises(ValueError, match="no bias correction"):
        convert_plots(frame, cart, b, bias=BIAS)
    site = SITES[0]
    frame = SystemFrame.ned(site.lat, site.lon, site.alt)
    D, psi, h = np.array([2000.0, 80e3]), np.array([0.3, 1.0]), np.array([3000.0, 9000.0])
    c = convert_plots(frame, site, _batch(site, D, psi, None, h, np.zeros(2, np.int64)),
                      debias=True)  # fmt: skip
    assert c.valid.all() and c.near_radar.tolist() == [True, False]
    assert np.isfinite(c.R).all()
