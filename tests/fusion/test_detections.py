"""Measurement batches from a user's detections (fusion/tracker/detections.py), checked
against independent conversions: pyproj's oblique stereographic projection and pymap3d's
ENU, and covariances against finite differences of those conversions."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pymap3d
import pytest
from pyproj import Proj
from skyfuse.fusion.frames import SystemFrame
from skyfuse.fusion.tracker import (
    Tracker,
    TrackerConfig,
    batch_from_positions,
    batch_from_wgs84,
)

LAT0, LON0 = 41.3, 2.1
# detections up to ≈ 150 km from the frame's centre
LAT = np.array([41.3, 41.9, 40.4, 42.5, 41.0])
LON = np.array([2.1, 3.0, 1.2, 3.9, 0.5])
ALT = np.array([100.0, 3000.0, 11000.0, 500.0, 7000.0])


def _sterea():
    return Proj(proj="sterea", lat_0=LAT0, lon_0=LON0, k_0=1.0, ellps="WGS84")


def _numeric_jacobian(to_plane, lat, lon, alt, step=1.0):
    """∂(x, y, z)/∂(e, n, u) by central differences: each point moved ±step m along its
    own local east, north and up (pymap3d.enu2geodetic), then mapped by ``to_plane``."""
    J = np.zeros((len(lat), 3, 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = step
        plus = pymap3d.enu2geodetic(*d, lat, lon, alt)
        minus = pymap3d.enu2geodetic(*(-d), lat, lon, alt)
        J[:, :, j] = (np.stack(to_plane(*plus), -1) - np.stack(to_plane(*minus), -1)) / (2 * step)
    return J


def test_local_positions_give_diagonal_covariances():
    xy = np.array([[0.0, 0.0], [1000.0, -2000.0], [5.0, 7.0]])
    b = batch_from_positions(12.5, xy, [10.0, 20.0, 30.0], p_detection=0.8)
    assert b.time_ns == 12_500_000_000
    np.testing.assert_array_equal(b.z, xy)
    np.testing.assert_array_equal(b.R[1], np.diag([400.0, 400.0]))
    per_axis = batch_from_positions(0.0, xy, np.array([[1.0, 2.0]] * 3))
    np.testing.assert_array_equal(per_axis.R[2], np.diag([1.0, 4.0]))
    three = batch_from_positions(0.0, np.zeros((2, 3)), 5.0)
    assert three.R.shape == (2, 3, 3) and three.R[0, 2, 2] == 25.0
    empty = batch_from_positions(0.0, np.zeros((0, 2)), 5.0)
    assert len(empty) == 0 and empty.R.shape == (0, 2, 2)


def test_aware_datetime_is_unix_nanoseconds():
    t = dt.datetime(2023, 5, 2, 8, 0, 1, 500000, tzinfo=dt.UTC)
    b = batch_from_positions(t, np.zeros((1, 2)), 1.0)
    assert b.time_ns == 1683014401_500_000_000
    with pytest.raises(ValueError, match="timezone-aware"):
        batch_from_positions(dt.datetime(2023, 5, 2), np.zeros((1, 2)), 1.0)


@pytest.mark.parametrize(
    ("positions", "sigma", "match"),
    [
        (np.zeros((3, 4)), 1.0, "expected \\(m, 2\\)"),
        (np.zeros((3, 2)), [1.0, 2.0], "sigma has shape"),
        (np.zeros((3, 2)), 0.0, "> 0"),
        (np.zeros((3, 2)), np.nan, "> 0"),
    ],
)
def test_bad_input_is_refused_with_the_reason(positions, sigma, match):
    with pytest.raises(ValueError, match=match):
        batch_from_positions(0.0, positions, sigma)


def test_wgs84_positions_in_the_stereographic_frame_match_pyproj():
    frame = SystemFrame.stereographic(LAT0, LON0)
    b = batch_from_wgs84(0.0, LAT, LON, 50.0, frame, alt=ALT, sigma_alt=80.0)
    x, y = _sterea()(LON, LAT)
    np.testing.assert_allclose(b.z[:, 0], x, atol=1e-6)
    np.testing.assert_allclose(b.z[:, 1], y, atol=1e-6)
    np.testing.assert_allclose(b.z[:, 2], ALT)
    flat = batch_from_wgs84(0.0, LAT, LON, 50.0, frame)
    np.testing.assert_allclose(flat.z, np.stack([x, y], -1), atol=1e-6)


def test_wgs84_positions_in_the_ned_frame_match_pymap3d():
    frame = SystemFrame.ned(LAT0, LON0, 20.0)
    b = batch_from_wgs84(0.0, LAT, LON, 50.0, frame, alt=ALT, sigma_alt=80.0)
    e, n, u = pymap3d.geodetic2enu(LAT, LON, ALT, LAT0, LON0, 20.0)
    np.testing.assert_allclose(b.z, np.stack([e, n, u], -1), atol=1e-6)


@pytest.mark.parametrize("kind", ["stereographic", "ned"])
def test_wgs84_covariance_is_the_propagated_local_error(kind):
    """R = J diag(σ²) Jᵀ with J from finite differences of the independent conversion."""
    if kind == "stereographic":
        frame = SystemFrame.stereographic(LAT0, LON0)
        proj = _sterea()

        def to_plane(lat, lon, alt):
            x, y = proj(lon, lat)
            return x, y, alt
    else:
        frame = SystemFrame.ned(LAT0, LON0, 20.0)

        def to_plane(lat, lon, alt):
            return pymap3d.geodetic2enu(lat, lon, alt, LAT0, LON0, 20.0)

    sig = np.array([[30.0, 60.0]] * len(LAT))
    b = batch_from_wgs84(0.0, LAT, LON, sig, frame, alt=ALT, sigma_alt=90.0)
    J = _numeric_jacobian(to_plane, LAT, LON, ALT)
    D = np.diag([30.0**2, 60.0**2, 90.0**2])
    np.testing.assert_allclose(b.R, J @ D @ np.swapaxes(J, 1, 2), rtol=1e-5, atol=1e-3)
    flat = batch_from_wgs84(0.0, LAT, LON, sig, frame)
    J0 = _numeric_jacobian(to_plane, LAT, LON, np.zeros_like(LAT))[:, :2, :2]
    np.testing.assert_allclose(flat.R, J0 @ D[:2, :2] @ np.swapaxes(J0, 1, 2), rtol=1e-5, atol=1e-3)


def test_wgs84_height_needs_its_sigma():
    frame = SystemFrame.stereographic(LAT0, LON0)
    with pytest.raises(ValueError, match="sigma_alt"):
        batch_from_wgs84(0.0, LAT, LON, 50.0, frame, alt=ALT)


def test_a_tracker_fed_local_detections_confirms_both_targets():
    """Two straight targets seen every 4 s with σ = 50 m among 20 uniform false plots per
    scan: after 30 scans both are confirmed within a few σ of the truth, and no false
    track is confirmed."""
    rng = np.random.default_rng(7)
    tracker = Tracker(TrackerConfig(tracker="lmits"))
    area = 100e3**2
    for k in range(30):
        t = 4.0 * k
        truth = np.array([[1000 + 200 * t, 5000.0], [20000.0, -3000 + 150 * t]])
        plots = np.vstack([truth + rng.normal(0, 50, (2, 2)), rng.uniform(-50e3, 50e3, (20, 2))])
        out = tracker.step(batch_from_positions(t, plots, 50.0, clutter_density=20 / area))
    pos = out.states[out.confirmed][:, [0, 2]]
    assert len(pos) == 2
    err = np.linalg.norm(pos[:, None, :] - truth[None, :, :], axis=-1).min(axis=0)
    assert np.all(err < 300.0), err
