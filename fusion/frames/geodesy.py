"""WGS-84 helpers that pymap3d does not give directly ([LIT] WGS-84 geodesy).

Geodetic ↔ ECEF ↔ ENU conversions themselves are pymap3d's (``geodetic2enu``,
``enu2geodetic``, ``enu2uvw``, ``uvw2enu``); this module adds the pieces the plot
conversion needs: radii of curvature of the ellipsoid, the rotation between two
local ENU frames, and a fast ENU → geodetic path (:func:`enu_to_geodetic`: the ENU →
ECEF rotation in NumPy, ECEF → geodetic by PROJ's ``cart`` inverse in C) — the same
numbers as ``pymap3d.enu2geodetic`` (sub-micrometre) at a fraction of its per-call cost,
which matters on the tracker's per-batch path. Angles are degrees unless a name says
``_rad``; lengths metres.
"""

from __future__ import annotations

import functools

import numpy as np
from pyproj import Transformer

WGS84_A = 6_378_137.0
"""WGS-84 semi-major axis, m."""
WGS84_F = 1.0 / 298.257223563
"""WGS-84 flattening."""
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
"""WGS-84 first eccentricity squared."""


def meridian_radius(lat_deg) -> np.ndarray:
    """Radius of curvature in the meridian M(φ), m."""
    s = np.sin(np.radians(lat_deg))
    return WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * s * s) ** 1.5


def prime_vertical_radius(lat_deg) -> np.ndarray:
    """Radius of curvature in the prime vertical N(φ), m."""
    s = np.sin(np.radians(lat_deg))
    return WGS84_A / np.sqrt(1.0 - WGS84_E2 * s * s)


def normal_section_radius(lat_deg, azimuth_rad) -> np.ndarray:
    """Euler's radius of curvature of the normal section at latitude φ in direction α
    (clockwise from north): 1/R_α = cos²α/M + sin²α/N, m. The local Earth radius used to
    solve a 2-D radar's elevation along the plot's azimuth."""
    c2 = np.cos(azimuth_rad) ** 2
    return 1.0 / (c2 / meridian_radius(lat_deg) + (1.0 - c2) / prime_vertical_radius(lat_deg))


def ecef_to_enu_rotation(lat_deg, lon_deg) -> np.ndarray:
    """Rotation matrix (…, 3, 3) taking ECEF vector components to local (east, north, up)
    components at geodetic (lat, lon)."""
    phi = np.radians(np.asarray(lat_deg, float))
    lam = np.radians(np.asarray(lon_deg, float))
    sp, cp, sl, cl = np.sin(phi), np.cos(phi), np.sin(lam), np.cos(lam)
    R = np.empty((*np.broadcast_shapes(sp.shape, sl.shape), 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = -sl, cl, 0.0
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = -sp * cl, -sp * sl, cp
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = cp * cl, cp * sl, sp
    return R


@functools.lru_cache(maxsize=4096)
def _site_frame(lat0: float, lon0: float, alt0: float | None) -> tuple[np.ndarray, np.ndarray]:
    """ECEF → ENU rotation at one geodetic point and, with ``alt0``, its ECEF position:
    the same arithmetic as :func:`ecef_to_enu_rotation` / :func:`geodetic_to_ecef`, done
    once per radar site (a batch converts hundreds of plots of one site, and the scalar
    set-up is ≈ 20 small NumPy calls). Read-only arrays, shared by the callers."""
    rot = ecef_to_enu_rotation(lat0, lon0)
    origin = np.zeros(3) if alt0 is None else geodetic_to_ecef(lat0, lon0, alt0)
    rot.flags.writeable = origin.flags.writeable = False
    return rot, origin


def _rotation(lat_deg, lon_deg) -> np.ndarray:
    """:func:`ecef_to_enu_rotation`, from the per-site cache for one scalar point."""
    if np.ndim(lat_deg) == 0 and np.ndim(lon_deg) == 0:
        return _site_frame(float(lat_deg), float(lon_deg), None)[0]
    return ecef_to_enu_rotation(lat_deg, lon_deg)


def enu_to_enu_rotation(lat_from, lon_from, lat_to, lon_to) -> np.ndarray:
    """Rotation (…, 3, 3) taking ENU components at (lat_from, lon_from) to ENU components
    at (lat_to, lon_to): R_to · R_fromᵀ."""
    r_from = _rotation(lat_from, lon_from)
    r_to = _rotation(lat_to, lon_to)
    return r_to @ np.swapaxes(r_from, -1, -2)


def geodetic_to_ecef(lat_deg, lon_deg, alt_m) -> np.ndarray:
    """WGS-84 geodetic (deg, deg, m) → ECEF (…, 3), m (closed form)."""
    phi = np.radians(np.asarray(lat_deg, float))
    lam = np.radians(np.asarray(lon_deg, float))
    h = np.asarray(alt_m, float)
    N = prime_vertical_radius(lat_deg)
    cp = np.cos(phi)
    return np.stack(
        [
            (N + h) * cp * np.cos(lam),
            (N + h) * cp * np.sin(lam),
            (N * (1.0 - WGS84_E2) + h) * np.sin(phi),
        ],
        axis=-1,
    )


def enu_to_ecef(enu: np.ndarray, lat0: float, lon0: float, alt0: float) -> np.ndarray:
    """Points (m, 3) in the local ENU frame at (lat0, lon0, alt0) → ECEF (m, 3), m."""
    rot, origin = _site_frame(float(lat0), float(lon0), float(alt0))
    return origin + np.asarray(enu, float).reshape(-1, 3) @ rot


@functools.lru_cache(maxsize=1)
def _ecef_to_geodetic() -> Transformer:
    """PROJ: geocentric WGS-84 (EPSG:4978) → geodetic 3-D (EPSG:4979), lon/lat order."""
    return Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)


def ecef_to_geodetic(ecef: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF (m, 3), m → (lat deg, lon deg, height above the ellipsoid m) by PROJ."""
    ecef = np.asarray(ecef, float).reshape(-1, 3)
    lon, lat, h = _ecef_to_geodetic().transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
    return np.asarray(lat), np.asarray(lon), np.asarray(h)


def enu_to_geodetic(
    enu: np.ndarray, lat0: float, lon0: float, alt0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (m, 3) in the ENU frame at (lat0, lon0, alt0) → (lat deg, lon deg, h m);
    the same mapping as ``pymap3d.enu2geodetic``."""
    return ecef_to_geodetic(enu_to_ecef(enu, lat0, lon0, alt0))
