"""Measurement batches from a user's own detections: positions in the system frame, or
WGS-84 latitude/longitude (and height), each with its position error.

The tracker works on :class:`~skyfuse.fusion.tracker.MeasurementBatch` (positions z in
the system frame, metres, covariances R in m², time in integer ns). These two
constructors build one from what a detector usually gives:

* :func:`batch_from_positions` — positions already in a local Cartesian frame (x east,
  y north[, z up], metres) with a standard deviation σ per plot (or per plot and axis):
  R = diag(σ_x², σ_y²[, σ_z²]).
* :func:`batch_from_wgs84` — latitude, longitude (degrees, WGS-84) and optionally the
  height above the ellipsoid (m), with a horizontal σ in metres along the local east and
  north (and σ_alt vertically). Positions go into a :class:`~skyfuse.fusion.frames.SystemFrame`
  with :meth:`~skyfuse.fusion.frames.SystemFrame.from_geodetic`; the covariance is carried
  by the frame's local Jacobian J = ∂(x, y, z)/∂(e, n, u) at each point
  (:meth:`~skyfuse.fusion.frames.SystemFrame.local_plane_jacobian`: the grid convergence
  and point scale of the stereographic plane, or the rotation into the reference point's
  tangent plane of an ``ned`` frame):

      R = J diag(σ_e², σ_n², σ_u²) Jᵀ     (2-D: J's upper-left 2 × 2 block and σ_e, σ_n)

Times are seconds (any epoch, e.g. UNIX time; only differences matter to the tracker) or
a timezone-aware :class:`datetime.datetime`.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
from skyfuse.fusion.frames import SystemFrame

from .measurements import MeasurementBatch

__all__ = ["batch_from_positions", "batch_from_wgs84", "time_ns"]

_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)


def time_ns(time: float | dt.datetime) -> int:
    """Seconds (float) or an aware datetime → integer nanoseconds (the tracker's clock)."""
    if isinstance(time, dt.datetime):
        if time.tzinfo is None:
            raise ValueError(f"time = {time!r}: give a timezone-aware datetime (e.g. UTC)")
        return (time - _EPOCH) // dt.timedelta(microseconds=1) * 1000  # exact integer µs
    t = float(time)
    if not np.isfinite(t):
        raise ValueError(f"time = {time!r}: must be finite seconds")
    return round(t * 1e9)


def _sigmas(sigma, m: int, ndim: int) -> np.ndarray:
    """σ as (m, ndim): a scalar, (m,) per plot, or (m, ndim) per plot and axis."""
    s = np.asarray(sigma, dtype=np.float64)
    if s.ndim == 0:
        s = np.full((m, ndim), float(s))
    elif s.shape == (m,):
        s = np.repeat(s[:, None], ndim, axis=1)
    elif s.shape != (m, ndim):
        raise ValueError(f"sigma has shape {s.shape}: expected a scalar, ({m},) or ({m}, {ndim})")
    if not np.all(np.isfinite(s) & (s > 0)):
        raise ValueError("sigma: every value must be finite and > 0 m")
    return s


def _diagonal(s: np.ndarray) -> np.ndarray:
    """(m, d) standard deviations → (m, d, d) diagonal covariances."""
    m, d = s.shape
    R = np.zeros((m, d, d))
    idx = np.arange(d)
    R[:, idx, idx] = s**2
    return R


def batch_from_positions(
    time: float | dt.datetime,
    positions,
    sigma,
    *,
    radar_id: str = "sensor",
    p_detection: float = 0.9,
    clutter_density: float = 0.0,
    target_ids=None,
) -> MeasurementBatch:
    """One scan of detections at ``positions`` (m, 2) or (m, 3) in the system frame (x east,
    y north[, z up], m) with standard deviation ``sigma`` (m: scalar, (m,) or (m, d)).

    ``p_detection``: the sensor's P_D; ``clutter_density``: false detections per m² (per
    m³ in 3-D) per scan (the tracker floors it at ``clutter_density_floor``);
    ``target_ids`` (m,): optional labels for evaluation, never used to associate."""
    z = np.asarray(positions, dtype=np.float64)
    if z.size == 0:
        z = z.reshape(0, z.shape[-1] if z.ndim == 2 else 2)
    if z.ndim != 2 or z.shape[1] not in (2, 3):
        raise ValueError(f"positions has shape {z.shape}: expected (m, 2) or (m, 3)")
    m, d = z.shape
    return MeasurementBatch(
        time_ns=time_ns(time),
        radar_id=radar_id,
        z=z.copy(),
        R=_diagonal(_sigmas(sigma, m, d)),
        p_detection=p_detection,
        clutter_density=clutter_density,
        target_ids=None if target_ids is None else np.asarray(target_ids),
    )


def batch_from_wgs84(
    time: float | dt.datetime,
    lat,
    lon,
    sigma,
    frame: SystemFrame,
    *,
    alt=None,
    sigma_alt=None,
    radar_id: str = "sensor",
    p_detection: float = 0.9,
    clutter_density: float = 0.0,
    target_ids=None,
) -> MeasurementBatch:
    """One scan of detections at WGS-84 ``lat``, ``lon`` (degrees, (m,)) in ``frame``.

    ``sigma``: horizontal standard deviation, m (scalar, (m,), or (m, 2) for east and
    north). Without ``alt`` the batch is 2-D (positions at height 0 m, x and y);
    with ``alt`` (m above the ellipsoid, (m,)) and ``sigma_alt`` (m) it is 3-D. The
    covariance is R = J diag(σ²) Jᵀ with J the frame's local Jacobian at each point
    (module docstring). The other arguments are those of :func:`batch_from_positions`."""
    lat = np.atleast_1d(np.asarray(lat, dtype=np.float64))
    lon = np.atleast_1d(np.asarray(lon, dtype=np.float64))
    if lat.shape != lon.shape or lat.ndim != 1:
        raise ValueError(f"lat {lat.shape} and lon {lon.shape} must be the same (m,) shape")
    m = len(lat)
    three_d = alt is not None
    if three_d and sigma_alt is None:
        raise ValueError("alt given without sigma_alt: give the height's σ in metres")
    h = np.zeros(m) if alt is None else np.broadcast_to(np.asarray(alt, float), (m,)).copy()
    x, y, z = frame.from_geodetic(lat, lon, h)
    d = 3 if three_d else 2
    s = _sigmas(sigma, m, 2)
    if three_d:
        s = np.concatenate([s, _sigmas(sigma_alt, m, 1)], axis=1)
    J = frame.local_plane_jacobian(lat, lon, h)[:, :d, :d]
    R = J @ _diagonal(s) @ np.swapaxes(J, 1, 2)
    pos = np.stack([x, y, z], axis=-1)[:, :d]
    return MeasurementBatch(
        time_ns=time_ns(time),
        radar_id=radar_id,
        z=pos,
        R=R,
        p_detection=p_detection,
        clutter_density=clutter_density,
        target_ids=None if target_ids is None else np.asarray(target_ids),
    )
