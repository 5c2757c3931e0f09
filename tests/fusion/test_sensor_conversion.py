"""Plots of sensors beyond the rotating radar converted into the system frame: ADS-B
(``wgs84``), multilateration (``cartesian`` with per-plot σ and heights) and a surface
movement radar (``2d`` polar plots at the surface height). Each covariance is checked
against a Monte Carlo of the sensor's own error model, propagated with pymap3d and pyproj
(never with the conversion's Jacobians): the sample covariance of the converted noisy
positions about the true one, and the average NEES within chi-square bounds."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from scipy import stats
from skyfuse.fusion.frames import SystemFrame, convert_plots
from skyfuse.schemas import PlotBatch, RadarSite

LAT0, LON0 = 41.3, 2.1  # LEBL
N = 12000


def _frames():
    return [SystemFrame.stereographic(LAT0, LON0), SystemFrame.ned(LAT0, LON0, 0.0)]


def _batch(radar_id: str, n: int, **cols) -> PlotBatch:
    values = {k: [None if v != v else float(v) for v in c] for k, c in cols.items()}
    return PlotBatch(
        radar_id=radar_id, scan=0, seq=0, time_start=0, time_end=0, time=[0] * n, **values
    )


def _check(c, truth, ndim):
    """Sample covariance of the converted positions about the truth within 6 standard
    errors of a sample variance of the mean R (Frobenius), and the NEES inside the
    99.9 % chi-square bounds."""
    d = c.z - truth[..., :ndim]
    sample = d.T @ d / len(d)
    R = c.R.mean(axis=0)
    assert np.linalg.norm(sample - R) < 6 * np.sqrt(2 / len(d)) * np.linalg.norm(R), (sample, R)
    nees = np.einsum("ni,ni->n", d, np.linalg.solve(c.R, d[..., None])[..., 0]).mean()
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], len(d) * ndim) / len(d)
    assert lo < nees < hi, (nees, lo, hi)


@pytest.mark.parametrize("frame", _frames(), ids=["stereographic", "ned"])
@pytest.mark.parametrize(("east_km", "north_km", "height", "measured"),
                         [(1.0, 2.0, 5.0, False), (60.0, -70.0, 9000.0, True),
                          (-20.0, 30.0, 3000.0, False)])  # fmt: skip
def test_wgs84_plot_covariance_matches_monte_carlo_of_enu_noise_at_the_aircraft(
    frame, east_km, north_km, height, measured
):
    """ADS-B: N(0, σ²) east and north at the aircraft's own position (σ per plot), the
    height measured (σ_altitude) or assumed (σ of the assumption); ndim 2 and 3."""
    rng = np.random.default_rng(int(east_km) + 100)
    site = RadarSite(radar_id="a", lat=LAT0, lon=LON0, alt=4.0, kind="wgs84",
                     sigma_altitude=20.0)  # fmt: skip
    lat, lon, h = pymap3d.enu2geodetic(east_km * 1e3, north_km * 1e3, 0.0, LAT0, LON0, height)
    sig = rng.choice([4.0, 12.0, 38.0], N)  # per-plot σ, as NACp/NUCp give them
    sig_h = 20.0 if measured else 3000.0
    dh = rng.normal(0, sig_h, N)
    # measured: the aircraft at h, its reported height off by dh; assumed: the aircraft at
    # h + dh (unknown), the plot placed at the assumed h
    h_true = np.full(N, h) if measured else h + dh
    e, n = rng.normal(0, 1, N) * sig, rng.normal(0, 1, N) * sig
    plat, plon, _ = pymap3d.enu2geodetic(e, n, 0.0, lat, lon, h_true)
    cols = {"lat": plat, "lon": plon, "sigma": sig}
    if measured:
        cols["altitude"] = h + dh
    b = _batch("a", N, **cols)
    truth = np.stack(frame.from_geodetic(np.full(N, lat), np.full(N, lon), h_true), -1)
    for ndim in (2, 3):
        c = convert_plots(frame, site, b, ndim=ndim, assumed_altitude=None if measured else h,
                          sigma_assumed_altitude=sig_h)  # fmt: skip
        # one σ class at a time (the NEES holds for each; the covariance check per class)
        for s in (4.0, 12.0, 38.0):
            rows = np.flatnonzero(sig == s)
            _check(c.take(rows), truth[rows], ndim)


@pytest.mark.parametrize("frame", _frames(), ids=["stereographic", "ned"])
@pytest.mark.parametrize(("east_m", "north_m", "height"),
                         [(300.0, -700.0, 4.0), (3850.0, -17133.0, 2545.0)])  # fmt: skip
def test_cartesian_plot_with_its_own_sigma_and_height_matches_monte_carlo(
    frame, east_m, north_m, height
):
    """Multilateration: N(0, σ²) along x east and y north of the reference point's tangent
    plane (σ from the plot: I500), the height of the plot's altitude column (σ_altitude)."""
    rng = np.random.default_rng(int(east_m))
    site = RadarSite(radar_id="m", lat=41.29706278, lon=2.07844722, alt=4.0, kind="cartesian",
                     sigma_cartesian=50.0, sigma_altitude=15.0)  # fmt: skip
    sig = np.full(N, 6.0)
    x = east_m + rng.normal(0, 6.0, N)
    y = north_m + rng.normal(0, 6.0, N)
    alt = height + rng.normal(0, 15.0, N)
    b = _batch("m", N, x=x, y=y, sigma=sig, altitude=alt)
    lat, lon, h = pymap3d.enu2geodetic(east_m, north_m, height - site.alt, site.lat, site.lon,
                                       site.alt)  # fmt: skip
    truth = np.stack(frame.from_geodetic(lat, lon, h), -1)
    for ndim in (2, 3):
        c = convert_plots(frame, site, b, ndim=ndim)
        _check(c, truth, ndim)
    # without the plot's σ the site's σ_cartesian applies: 50 m, not 6 m
    b2 = _batch("m", 3, x=x[:3], y=y[:3], sigma=[np.nan, 6.0, np.nan])
    R = convert_plots(frame, site, b2).R
    assert np.sqrt(np.trace(R[0]) / 2) == pytest.approx(50.0, rel=2e-3)
    assert np.sqrt(np.trace(R[1]) / 2) == pytest.approx(6.0, rel=2e-3)


@pytest.mark.parametrize("frame", _frames(), ids=["stereographic", "ned"])
@pytest.mark.parametrize(("range_m", "az_deg"), [(600.0, 80.0), (2700.0, 265.0)])
def test_surface_radar_polar_plot_at_the_surface_height_matches_monte_carlo(frame, range_m, az_deg):
    """A surface movement radar: slant range and azimuth noise of a target on the surface
    (height = the site's, σ_altitude of a surface), through pymap3d's AER."""
    rng = np.random.default_rng(int(range_m))
    site = RadarSite(radar_id="s", lat=41.29561833, lon=2.09511417, alt=4.0, kind="2d",
                     sigma_range=6.0, sigma_azimuth=1.5e-3, sigma_altitude=3.0)  # fmt: skip
    e, n = range_m * np.sin(np.radians(az_deg)), range_m * np.cos(np.radians(az_deg))
    lat, lon, _ = pymap3d.enu2geodetic(e, n, 0.0, site.lat, site.lon, site.alt)
    az, _, sr = pymap3d.geodetic2aer(lat, lon, site.alt, site.lat, site.lon, site.alt)
    D = sr + rng.normal(0, site.sigma_range, N)
    psi = (np.radians(az) + rng.normal(0, site.sigma_azimuth, N)) % (2 * np.pi)
    alt = site.alt + rng.normal(0, site.sigma_altitude, N)
    b = _batch("s", N, range=D, azimuth=psi, altitude=alt)
    truth = np.stack(frame.from_geodetic(lat, lon, site.alt), -1)
    c = convert_plots(frame, site, b, ndim=2)
    assert c.valid.all() and not c.near_radar.any()
    _check(c, truth, 2)


@pytest.mark.parametrize("frame", _frames(), ids=["stereographic", "ned"])
def test_reported_velocity_is_the_frame_rate_of_change_of_the_position(frame):
    """(v_east, v_north) at the plot → the frame velocity equals the change of the frame
    position of the aircraft moved by v·dt in its own ENU (pymap3d, pyproj)."""
    site = RadarSite(radar_id="a", lat=LAT0, lon=LON0, alt=4.0, kind="wgs84")
    lat, lon, h = pymap3d.enu2geodetic(50e3, 40e3, 0.0, LAT0, LON0, 8000.0)
    ve, vn, dt = 180.0, -120.0, 0.01
    b = _batch("a", 1, lat=[lat], lon=[lon], altitude=[h], v_east=[ve], v_north=[vn],
               sigma_velocity=[1.2])  # fmt: skip
    c = convert_plots(frame, site, b)
    lat2, lon2, h2 = pymap3d.enu2geodetic(ve * dt, vn * dt, 0.0, lat, lon, h)
    p1 = np.array(frame.from_geodetic(lat, lon, h))[:2]
    p2 = np.array(frame.from_geodetic(lat2, lon2, h2))[:2]
    np.testing.assert_allclose(c.velocity[0], (p2 - p1) / dt, atol=2e-3)
    assert c.velocity_var[0] == pytest.approx(1.44)


def test_plots_of_another_geometry_than_the_site_are_refused():
    frame = SystemFrame.stereographic(LAT0, LON0)
    adsb = RadarSite(radar_id="a", lat=LAT0, lon=LON0, kind="wgs84")
    with pytest.raises(ValueError, match="wgs84 sensor but its batch does not carry lat/lon"):
        convert_plots(frame, adsb, _batch("a", 1, x=[1.0], y=[2.0]))
    radar = RadarSite(radar_id="a", lat=LAT0, lon=LON0, kind="2d")
    with pytest.raises(ValueError, match="2d sensor"):
        convert_plots(frame, radar, _batch("a", 1, lat=[LAT0], lon=[LON0]))
