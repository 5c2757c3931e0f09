"""System frames and plot conversion against independent references: pyproj and pymap3d
called directly, pyproj's projection factors, and Monte Carlo consistency."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from pyproj import CRS, Proj, Transformer
from scipy import stats
from skyfuse.fusion.frames import Stereographic, SystemFrame, convert_plots
from skyfuse.schemas import FrameKind, FrameSpec, PlotBatch, RadarSite

LAT0, LON0 = 44.8, 20.45


def _targets(n, radius_km, seed=0):
    """Geodetic points within ~radius_km of the centre, altitudes 0-12 km."""
    rng = np.random.default_rng(seed)
    r = radius_km * 1e3 * np.sqrt(rng.uniform(0, 1, n))
    a = rng.uniform(0, 2 * np.pi, n)
    lat, lon, _ = pymap3d.enu2geodetic(r * np.sin(a), r * np.cos(a), 0.0, LAT0, LON0, 0.0)
    return np.asarray(lat), np.asarray(lon), rng.uniform(0, 12_000, n)


def _batch(site, sr, az_deg, *, elevation=None, altitude=None):
    n = len(sr)
    kw = {}
    if elevation is not None:
        kw["elevation"] = [float(v) for v in elevation]
    if altitude is not None:
        kw["altitude"] = [None if not np.isfinite(v) else float(v) for v in altitude]
    return PlotBatch(
        radar_id=site.radar_id,
        scan=0,
        seq=0,
        time_start=0,
        time_end=0,
        time=[0] * n,
        range=[float(v) for v in sr],
        azimuth=[float(v) for v in np.radians(az_deg) % (2 * np.pi)],
        **kw,
    )


def test_stereographic_frame_matches_pyproj_directly_and_round_trips_to_300_km():
    frame = SystemFrame.stereographic(LAT0, LON0)
    lat, lon, alt = _targets(2000, 300)
    crs = CRS.from_proj4(f"+proj=sterea +lat_0={LAT0} +lon_0={LON0} +k_0=1 +ellps=WGS84")
    tr = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True)
    xr, yr = tr.transform(lon, lat)
    x, y, z = frame.from_geodetic(lat, lon, alt)
    assert np.abs(x - xr).max() < 1e-3 and np.abs(y - yr).max() < 1e-3
    np.testing.assert_array_equal(z, alt)
    la, lo, al = frame.to_geodetic(x, y, z)
    e, n, u = pymap3d.geodetic2enu(la, lo, al, lat, lon, alt)
    assert np.sqrt(e**2 + n**2 + u**2).max() < 1e-3  # millimetre round trip
    assert np.hypot(x, y).max() > 290e3


def test_ned_frame_matches_pymap3d_ned_and_round_trips():
    frame = SystemFrame.ned(LAT0, LON0, 150.0)
    lat, lon, alt = _targets(1000, 300, seed=1)
    n, e, d = pymap3d.geodetic2ned(lat, lon, alt, LAT0, LON0, 150.0)
    x, y, z = frame.from_geodetic(lat, lon, alt)
    assert max(np.abs(x - e).max(), np.abs(y - n).max(), np.abs(z + d).max()) < 1e-3
    nn, ee, dd = frame.to_ned(x, y, z)
    np.testing.assert_allclose([nn, ee, dd], [n, e, d], atol=1e-6)
    la, _lo, al = frame.to_geodetic(x, y, z)
    assert np.abs(la - lat).max() < 1e-10 and np.abs(al - alt).max() < 1e-3


def test_frame_spec_round_trip_and_bad_kind():
    for frame in (
        SystemFrame.stereographic(LAT0, LON0),
        SystemFrame.ned(LAT0, LON0, 10.0),
        SystemFrame.planar(),
    ):
        spec = frame.spec()
        assert isinstance(spec, FrameSpec)
        assert SystemFrame.from_spec(FrameSpec.from_json_bytes(spec.to_json_bytes())) == frame
    assert SystemFrame.from_config("ned", LAT0, LON0).kind is FrameKind.NED
    with pytest.raises(ValueError, match="frame kind = 'utm'"):
        SystemFrame.from_config("utm")
    with pytest.raises(ValueError, match="lat0 = 95"):
        SystemFrame.ned(95.0, 0.0)


def test_plane_jacobian_is_scale_times_grid_convergence_rotation_per_pyproj_factors():
    frame = SystemFrame.stereographic(LAT0, LON0)
    lat, lon, _ = _targets(50, 300, seed=2)
    J = frame.local_plane_jacobian(lat, lon, np.zeros_like(lat))  # on the ellipsoid
    f = Proj(frame._sterea.crs).get_factors(lon, lat)
    g = np.radians(np.asarray(f.meridian_convergence))
    k = np.asarray(f.meridional_scale)
    ref = k[:, None, None] * np.stack(
        [np.stack([np.cos(g), -np.sin(g)], -1), np.stack([np.sin(g), np.cos(g)], -1)], -2
    )
    np.testing.assert_allclose(J[:, :2, :2], ref, atol=2e-8)


@pytest.mark.parametrize(
    "kind_frame",
    [
        SystemFrame.stereographic(LAT0, LON0),
        SystemFrame.ned(LAT0, LON0, 0.0),
    ],
)
def test_noise_free_plots_of_two_radars_agree_to_centimetres(kind_frame):
    frame = kind_frame
    lat, lon, alt = _targets(300, 150, seed=3)
    alt = alt + 500
    sites = [
        RadarSite(radar_id="a", lat=44.1, lon=19.6, alt=350.0, kind="3d"),
        RadarSite(radar_id="b", lat=45.6, lon=21.4, alt=820.0, kind="2d"),
        RadarSite(radar_id="c", lat=LAT0, lon=LON0, alt=95.0, kind="2d"),
    ]
    ref = np.stack(frame.from_geodetic(lat, lon, alt), -1)
    out = []
    for s in sites:
        az, el, sr = pymap3d.geodetic2aer(lat, lon, alt, s.lat, s.lon, s.alt)
        if s.kind == "3d":
            b = _batch(s, sr, az, elevation=np.radians(el))
        else:
            b = _batch(s, sr, az, altitude=alt)
        c = convert_plots(frame, s, b, ndim=3)
        assert c.valid.all()
        # near-radar plots are the posterior mean on the range sphere, not the
        # noise-free point: within a small fraction of their σ; the others to centimetres
        far = ~c.near_radar
        assert np.abs(c.z[far] - ref[far]).max() < 0.01  # each radar vs pymap3d/pyproj
        for i in np.flatnonzero(c.near_radar):
            d = c.z[i, :2] - ref[i, :2]
            assert d @ np.linalg.solve(c.R[i, :2, :2], d) < 0.25  # within σ/2
        out.append(np.where(far[:, None], c.z, np.nan))
    for a, b in ((0, 1), (1, 2)):
        both = np.isfinite(out[a][:, 0]) & np.isfinite(out[b][:, 0])
        assert both.sum() > 100
        assert np.abs(out[a][both] - out[b][both]).max() < 0.02


def _monte_carlo(frame, site, rng_m, n, rng, *, az_deg=37.0, talt=9000.0):
    e, nn = rng_m * np.sin(np.radians(az_deg)), rng_m * np.cos(np.radians(az_deg))
    lat, lon, _ = pymap3d.enu2geodetic(e, nn, 0.0, site.lat, site.lon, site.alt)
    az, el, sr = pymap3d.geodetic2aer(lat, lon, talt, site.lat, site.lon, site.alt)
    D = sr + rng.normal(0, site.sigma_range, n)
    psi = np.radians(az) + rng.normal(0, site.sigma_azimuth, n)
    if site.kind == "3d":
        b = _batch(
            site,
            D,
            np.degrees(psi),
            elevation=np.radians(el) + rng.normal(0, site.sigma_elevation, n),
        )
    else:
        b = _batch(site, D, np.degrees(psi), altitude=talt + rng.normal(0, site.sigma_altitude, n))
    ref = np.stack(frame.from_geodetic(lat, lon, talt), -1)
    radial = np.array([np.sin(np.radians(az_deg)), np.cos(np.radians(az_deg))])
    return b, ref, radial


@pytest.mark.parametrize("kind", ["2d", "3d"])
@pytest.mark.parametrize("range_km", [10, 100, 250])
@pytest.mark.parametrize("sigma_mrad", [0.5, 2.5, 6.0])
def test_converted_plot_nees_is_inside_chi_square_bounds(kind, range_km, sigma_mrad):
    """Average NEES of converted plots vs the true position, 99.9% two-sided chi-square
    bounds. Debiased: everywhere. Plain: where the Lerro-Bar-Shalom bias criterion
    r σ²/σ_r is below 0.4; above it the plain conversion must be visibly biased."""
    frame = SystemFrame.stereographic(LAT0, LON0)
    site = RadarSite(
        radar_id="r",
        lat=44.5,
        lon=20.0,
        alt=200.0,
        kind=kind,
        sigma_range=20.0,
        sigma_azimuth=sigma_mrad * 1e-3,
        sigma_elevation=sigma_mrad * 1e-3,
        sigma_altitude=30.0,
    )
    n = 1500
    rng = np.random.default_rng(int(range_km * 10 + sigma_mrad * 2) + (kind == "3d"))
    b, ref, _radial = _monte_carlo(frame, site, range_km * 1e3, n, rng)
    criterion = range_km * 1e3 * (sigma_mrad * 1e-3) ** 2 / site.sigma_range
    for ndim in (2, 3):
        lo, hi = stats.chi2.ppf([0.0005, 0.9995], n * ndim) / n
        for debias in (False, True):
            c = convert_plots(frame, site, b, ndim=ndim, debias=debias)
            d = c.z - ref[:ndim]
            nees = np.einsum("ni,ni->n", d, np.linalg.solve(c.R, d[..., None])[..., 0]).mean()
            if debias or criterion < 0.4:
                assert lo < nees < hi, (ndim, debias, nees, lo, hi)


def test_plain_conversion_is_biased_at_long_range_and_debiasing_removes_it():
    """At 250 km and 6 mrad the plain conversion is pulled toward the radar by
    D (1 − λ) ≈ D σ²/2 per angle (4.5 m for a 2-D radar, 9 m for a 3-D radar);
    the debiased conversion is not."""
    frame = SystemFrame.stereographic(LAT0, LON0)
    rng = np.random.default_rng(7)
    n = 20_000
    for kind, expected in (("2d", -4.5), ("3d", -9.0)):
        site = RadarSite(
            radar_id="r",
            lat=44.5,
            lon=20.0,
            alt=200.0,
            kind=kind,
            sigma_range=20.0,
            sigma_azimuth=6e-3,
            sigma_elevation=6e-3,
            sigma_altitude=30.0,
        )
        b, ref, radial = _monte_carlo(frame, site, 250e3, n, rng)
        plain = convert_plots(frame, site, b)
        deb = convert_plots(frame, site, b, debias=True)
        bias_plain = ((plain.z - ref[:2]) @ radial).mean()
        bias_deb = ((deb.z - ref[:2]) @ radial).mean()
        se = 21.0 / np.sqrt(n)
        assert abs(bias_plain - expected) < 5 * se + 0.3, (kind, bias_plain)
        assert abs(bias_deb) < 5 * se, (kind, bias_deb)


def test_two_d_plot_without_altitude_is_invalid_or_uses_the_assumed_altitude():
    frame = SystemFrame.stereographic(LAT0, LON0)
    site = RadarSite(radar_id="r", lat=LAT0, lon=LON0, alt=100.0, kind="2d")
    b = _batch(site, [80e3, 120e3, 500.0], [10.0, 200.0, 5.0], altitude=[np.nan, 9000.0, 9000.0])
    c = convert_plots(frame, site, b)
    # plot 2 (FL far above a 500 m slant range) is kept near the radar
    assert c.valid.tolist() == [False, True, True]
    assert c.near_radar.tolist() == [False, False, True] and c.n_near_radar == 1
    assert "no assumed_altitude" in c.reasons[0]
    assert c.reasons[1] == c.reasons[2] == "" and "near the radar" in c.notes[2]
    assert np.hypot(*(c.z[2] - c.site_position)) <= 500.0
    assert np.isnan(c.z[0]).all()
    c2 = convert_plots(frame, site, b, assumed_altitude=6000.0, sigma_assumed_altitude=3000.0)
    assert c2.valid.tolist() == [True, True, True] and "assumed" in c2.notes[0]
    # The large vertical sigma widens the horizontal covariance along the range.
    known = convert_plots(frame, site, _batch(site, [80e3], [10.0], altitude=[6000.0]), ndim=2)
    az = np.radians(10.0)
    u = np.array([np.sin(az), np.cos(az)])
    assert u @ c2.R[0] @ u > 20 * (u @ known.R[0] @ u)


def test_batch_site_mismatch_raises_a_clear_error():
    frame = SystemFrame.planar()
    site = RadarSite(radar_id="r", lat=0.0, lon=0.0, kind="2d")
    other = RadarSite(radar_id="q", lat=0.0, lon=0.0, kind="2d")
    b = _batch(site, [1000.0], [0.0], altitude=[0.0])
    with pytest.raises(ValueError, match=r"does not match site\.radar_id"):
        convert_plots(frame, other, b)
    cart = RadarSite(radar_id="r", lat=0.0, lon=0.0, kind="cartesian")
    with pytest.raises(ValueError, match="cartesian sensor"):
        convert_plots(frame, cart, b)


def test_planar_frame_cartesian_and_flat_polar_plots():
    frame = SystemFrame.planar(0.0, 0.0, 0.0)
    site = RadarSite(radar_id="c", lat=0.0, lon=0.0, alt=0.0, kind="cartesian", sigma_cartesian=7.0)
    b = PlotBatch(
        radar_id="c",
        scan=0,
        seq=0,
        time_start=5,
        time_end=6,
        time=[5, 6],
        x=[100.0, -250.0],
        y=[30.0, 4000.0],
    )
    c = convert_plots(frame, site, b)
    np.testing.assert_allclose(c.z, [[100.0, 30.0], [-250.0, 4000.0]], atol=1e-9)
    np.testing.assert_allclose(c.R, np.broadcast_to(49.0 * np.eye(2), (2, 2, 2)))
    assert c.time.tolist() == [5, 6]
    radar = RadarSite(
        radar_id="p", lat=0.0, lon=0.0, alt=0.0, kind="2d", sigma_range=20.0, sigma_azimuth=2.5e-3
    )
    th = np.radians(45.0)
    c = convert_plots(frame, radar, _batch(radar, [50e3], [45.0], altitude=[0.0]))
    # flat closed forms up to Earth curvature at 50 km (elevation −D/2R: < 1 m, 1e-3 in R)
    np.testing.assert_allclose(c.z[0], [50e3 * np.sin(th), 50e3 * np.cos(th)], atol=1.0)
    # [MZD] eq. 2 closed form for the 2-D covariance
    r, sr, st = 50e3, 20.0, 2.5e-3
    s, co = np.sin(th), np.cos(th)
    R = np.array(
        [
            [sr**2 * s**2 + r**2 * st**2 * co**2, s * co * (sr**2 - r**2 * st**2)],
            [s * co * (sr**2 - r**2 * st**2), sr**2 * co**2 + r**2 * st**2 * s**2],
        ]
    )
    np.testing.assert_allclose(c.R[0], R, rtol=1e-3)


def test_planar_frame_is_tied_to_the_earth_like_the_simulator_plane():
    """Planar scenarios map their plane to WGS-84 through sterea at (lat0, lon0)."""
    frame = SystemFrame.planar(LAT0, LON0)
    lat, lon, alt = _targets(100, 100, seed=9)
    x, y, _ = frame.from_geodetic(lat, lon, alt)
    xr, yr = Stereographic(LAT0, LON0).forward(lat, lon)
    np.testing.assert_allclose(np.stack([x, y]), np.stack([xr, yr]), atol=1e-6)
    # a 2-D radar of a planar scenario converts exactly like the stereographic frame
    site = RadarSite(radar_id="p", lat=LAT0, lon=LON0, alt=0.0, kind="2d")
    az, _, sr = pymap3d.geodetic2aer(lat, lon, alt, LAT0, LON0, 0.0)
    c = convert_plots(frame, site, _batch(site, sr, az, altitude=alt), ndim=3)
    np.testing.assert_allclose(c.z, np.stack([x, y, alt], -1), atol=0.01)


@pytest.mark.parametrize(
    "frame", [SystemFrame.stereographic(LAT0, LON0), SystemFrame.ned(LAT0, LON0, 0.0)]
)
def test_velocity_to_enu_matches_displacement_of_the_true_target(frame):
    lat, lon, alt = _targets(40, 250, seed=5)
    rng = np.random.default_rng(5)
    v = rng.uniform(-300, 300, (40, 3))
    v[:, 2] /= 20
    dt = 0.01
    la2, lo2, al2 = pymap3d.enu2geodetic(v[:, 0] * dt, v[:, 1] * dt, v[:, 2] * dt, lat, lon, alt)
    p1 = np.stack(frame.from_geodetic(lat, lon, alt), -1)
    p2 = np.stack(frame.from_geodetic(la2, lo2, al2), -1)
    vf = (p2 - p1) / dt
    ve, vn, vu = frame.velocity_to_enu(p1[:, 0], p1[:, 1], p1[:, 2], vf[:, 0], vf[:, 1], vf[:, 2])
    np.testing.assert_allclose(np.stack([ve, vn, vu], -1), v, atol=2e-3)


def test_elevation_from_altitude_matches_sphere_geometry_and_its_derivatives():
    """The 2-D elevation formula vs the elevation of a point placed on a sphere directly
    (radar at radius a, target at radius b, central angle γ), incl. the 4/3-Earth radius."""
    from skyfuse.fusion.frames.polar import elevation_from_altitude

    for R in (6_371e3, 4 / 3 * 6_371e3):
        hR = 300.0
        gamma = np.linspace(1e-3, 0.04, 30)
        hT = np.linspace(500.0, 12_000.0, 30)
        a, b = R + hR, R + hT
        D = np.sqrt(a * a + b * b - 2 * a * b * np.cos(gamma))
        sin_ref = (b * np.cos(gamma) - a) / D
        sol = elevation_from_altitude(D, hT, hR, R)
        np.testing.assert_allclose(np.sin(sol.theta), sin_ref, atol=1e-12)
        assert sol.feasible.all()
        h = 1e-3
        dD = (
            elevation_from_altitude(D + h, hT, hR, R).theta
            - elevation_from_altitude(D - h, hT, hR, R).theta
        ) / (2 * h)
        dh = (
            elevation_from_altitude(D, hT + h, hR, R).theta
            - elevation_from_altitude(D, hT - h, hR, R).theta
        ) / (2 * h)
        np.testing.assert_allclose(sol.dtheta_dD, dD, rtol=1e-5, atol=1e-12)
        np.testing.assert_allclose(sol.dtheta_dh, dh, rtol=1e-5, atol=1e-12)
    flat = elevation_from_altitude(np.array([1000.0]), np.array([600.0]), 100.0, np.inf)
    assert np.sin(flat.theta[0]) == pytest.approx(0.5)


def test_four_thirds_earth_option_changes_the_2d_solution_by_the_refraction_amount():
    frame = SystemFrame.stereographic(LAT0, LON0)
    site = RadarSite(radar_id="r", lat=LAT0, lon=LON0, alt=100.0, kind="2d")
    b = _batch(site, [150e3], [60.0], altitude=[9000.0])
    geo = convert_plots(frame, site, b)
    refr = convert_plots(frame, site, b, k_earth=4 / 3)
    # 4/3 Earth: less curvature drop → higher elevation θ for the same altitude → shorter
    # ground range, by ≈ D sinθ Δθ with Δθ ≈ (1 − 3/4) D/(2R) ≈ 3 mrad: about 20-40 m here
    shift = np.linalg.norm(refr.z[0]) - np.linalg.norm(geo.z[0])
    assert -60.0 < shift < -10.0
