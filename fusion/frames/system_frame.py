"""The system frame the tracker works in, chosen by configuration ([Dikić]).

**Tracker coordinates (one convention for every kind):** x east, y north, z up, metres
(velocities m/s along the same axes). What "east/north/up" means per kind:

* ``stereographic`` — (x, y) on the oblique stereographic plane of WGS-84 tangent at
  (lat0, lon0) (PROJ ``+proj=sterea``, k0 = 1, the FAA/NAS system plane); z is the
  height above the ellipsoid. For deployments wider than ~30 km.
* ``ned`` — the local tangent plane at the reference point (lat0, lon0, alt0):
  (x, y, z) = (east, north, up) of pymap3d's ENU at that point, i.e. exactly the NED
  frame of the wire convention (:class:`schemas.FrameKind`) with n = y, e = x, d = −z
  (:meth:`SystemFrame.to_ned`). For deployments under ~30 km ([Dikić]).
* ``planar`` — planar test scenarios where the plane *is* the frame (the simulator's
  scenario plane): cartesian test sensors' (x, y) plots are plane offsets from the site's
  plane position, added without curvature or rotation, with R = σ² I unchanged. The
  plane is tied to the Earth as the simulator ties it (:mod:`fusion.sim`): the
  stereographic plane at (lat0, lon0), so sites, polar radar plots and geodetic output
  are converted exactly as in ``stereographic``; z is the height.
"""

from __future__ import annotations

import functools

import numpy as np
import pymap3d
from pyproj import Proj
from skyfuse.schemas import FrameKind, FrameSpec

from .geodesy import (
    WGS84_A,
    enu_to_enu_rotation,
    enu_to_geodetic,
    meridian_radius,
    prime_vertical_radius,
)
from .stereographic import Stereographic


@functools.lru_cache(maxsize=64)
def _stereographic(lat0: float, lon0: float) -> Stereographic:
    """Shared projections: building pyproj transformers costs tens of ms."""
    return Stereographic(lat0, lon0)


@functools.lru_cache(maxsize=64)
def _plane_proj(lat0: float, lon0: float) -> Proj:
    """The same projection as a ``pyproj.Proj`` (for ``get_factors``)."""
    return Proj(_stereographic(lat0, lon0).crs)


class SystemFrame:
    """A configured system frame. Build with :meth:`stereographic`, :meth:`ned`,
    :meth:`planar`, :meth:`from_spec` or :meth:`from_config`.

    All methods are vectorised over NumPy arrays; angles in degrees, lengths in metres."""

    def __init__(
        self, kind: FrameKind | str, lat0: float = 0.0, lon0: float = 0.0, alt0: float = 0.0
    ) -> None:
        try:
            self.kind = FrameKind(kind)
        except ValueError:
            choices = ", ".join(k.value for k in FrameKind)
            raise ValueError(f"frame kind = {kind!r}: must be one of {choices}") from None
        for name, v, lo, hi in (("lat0", lat0, -90.0, 90.0), ("lon0", lon0, -180.0, 180.0)):
            if not (np.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{name} = {v}: must be a finite value in [{lo}, {hi}] degrees")
        if not np.isfinite(alt0):
            raise ValueError(f"alt0 = {alt0}: must be finite metres")
        self.lat0, self.lon0, self.alt0 = float(lat0), float(lon0), float(alt0)
        self._sterea = (
            _stereographic(self.lat0, self.lon0) if self.kind is not FrameKind.NED else None
        )

    # --- construction ------------------------------------------------------------------
    @classmethod
    def stereographic(cls, lat0: float, lon0: float) -> SystemFrame:
        return cls(FrameKind.STEREOGRAPHIC, lat0, lon0, 0.0)

    @classmethod
    def ned(cls, lat0: float, lon0: float, alt0: float = 0.0) -> SystemFrame:
        return cls(FrameKind.NED, lat0, lon0, alt0)

    @classmethod
    def planar(cls, lat0: float = 0.0, lon0: float = 0.0, alt0: float = 0.0) -> SystemFrame:
        return cls(FrameKind.PLANAR, lat0, lon0, alt0)

    @classmethod
    def from_spec(cls, spec: FrameSpec) -> SystemFrame:
        return cls(spec.kind, spec.lat0, spec.lon0, spec.alt0)

    @classmethod
    def from_config(
        cls, kind: str, lat0: float = 0.0, lon0: float = 0.0, alt0: float = 0.0
    ) -> SystemFrame:
        """From configuration values (``frame = "stereographic" | "ned" | "planar"``)."""
        return cls(kind, lat0, lon0, alt0)

    def spec(self) -> FrameSpec:
        """The wire description of this frame (published with every TrackBatch)."""
        return FrameSpec(kind=self.kind, lat0=self.lat0, lon0=self.lon0, alt0=self.alt0)

    def __repr__(self) -> str:
        return (
            f"SystemFrame({self.kind.value!r}, lat0={self.lat0}, lon0={self.lon0}, "
            f"alt0={self.alt0})"
        )

    def _key(self) -> tuple:
        return (self.kind, self.lat0, self.lon0, self.alt0)

    def __eq__(self, other: object) -> bool:
        # the fields of spec(), compared without building two wire models (this runs
        # on every batch: the site positions are cached by frame)
        return isinstance(other, SystemFrame) and self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    # --- positions ---------------------------------------------------------------------
    def from_geodetic(self, lat, lon, alt) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Geodetic (deg, deg, m above the ellipsoid) → frame (x east, y north, z up), m."""
        lat, lon, alt = (np.asarray(a, float) for a in (lat, lon, alt))
        if self._sterea is not None:
            x, y = self._sterea.forward(lat, lon)
            return x, y, np.array(alt, dtype=float, copy=True)
        e, n, u = pymap3d.geodetic2enu(lat, lon, alt, self.lat0, self.lon0, self.alt0)
        return tuple(np.asarray(a, float) for a in (e, n, u))

    def to_geodetic(self, x, y, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frame (x east, y north, z up), m → geodetic (lat deg, lon deg, alt m)."""
        x, y, z = (np.asarray(a, float) for a in (x, y, z))
        if self._sterea is not None:
            lat, lon = self._sterea.inverse(x, y)
            return lat, lon, np.array(z, dtype=float, copy=True)
        lat, lon, alt = pymap3d.enu2geodetic(x, y, z, self.lat0, self.lon0, self.alt0)
        return tuple(np.asarray(a, float) for a in (lat, lon, alt))

    def to_ned(self, x, y, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tracker (east, north, up) → the NED component order (north, east, down)."""
        return np.asarray(y, float), np.asarray(x, float), -np.asarray(z, float)

    def site_position(self, lat: float, lon: float, alt: float) -> np.ndarray:
        """A radar site's position in the frame, shape (3,) (a new array; computed once
        per frame and site: every batch of a radar needs it)."""
        return _site_position(self, float(lat), float(lon), float(alt)).copy()

    def enu_to_frame(self, enu: np.ndarray, lat_s: float, lon_s: float, alt_s: float):
        """Points given in the local ENU frame of a site (m, 3) → frame positions (m, 3).

        ``ned``: exact affine map ENU(site) → ECEF → ENU(reference);
        ``stereographic``/``planar``: ENU(site) → ECEF → geodetic (PROJ) → sterea plane +
        height (:func:`fusion.frames.geodesy.enu_to_geodetic`).
        """
        enu = np.asarray(enu, float).reshape(-1, 3)
        if self.kind is FrameKind.NED:
            lat, lon, alt = pymap3d.enu2geodetic(
                enu[:, 0], enu[:, 1], enu[:, 2], lat_s, lon_s, alt_s
            )
        else:
            lat, lon, alt = enu_to_geodetic(enu, lat_s, lon_s, alt_s)
        return np.stack(self.from_geodetic(lat, lon, alt), axis=-1)

    def enu_to_frame_with_jacobian(
        self, enu: np.ndarray, lat_s: float, lon_s: float, alt_s: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`enu_to_frame` and :meth:`enu_jacobian` of the same points in one pass
        (one geodetic conversion): positions (m, 3) and ∂(x, y, z)/∂(e, n, u) (m, 3, 3)."""
        enu = np.asarray(enu, float).reshape(-1, 3)
        m = enu.shape[0]
        if self.kind is FrameKind.NED:
            rot = enu_to_enu_rotation(lat_s, lon_s, self.lat0, self.lon0)
            return self.enu_to_frame(enu, lat_s, lon_s, alt_s), np.broadcast_to(
                rot, (m, 3, 3)
            ).copy()
        lat, lon, alt = enu_to_geodetic(enu, lat_s, lon_s, alt_s)
        pos = np.stack(self.from_geodetic(lat, lon, alt), axis=-1)
        # chain rule: site ENU → the point's own ENU (a rotation) → the plane
        J = self.local_plane_jacobian(lat, lon, alt) @ enu_to_enu_rotation(lat_s, lon_s, lat, lon)
        return pos, J

    def enu_jacobian(self, enu: np.ndarray, lat_s: float, lon_s: float, alt_s: float):
        """∂(x, y, z)/∂(e, n, u) of :meth:`enu_to_frame` at the given site-ENU points, (m, 3, 3).

        ``ned``: the constant rotation R_ref R_siteᵀ (exact); ``stereographic``/``planar``:
        the rotation from the site's ENU to the point's own ENU followed by
        :meth:`local_plane_jacobian` (grid convergence and point scale)."""
        return self.enu_to_frame_with_jacobian(enu, lat_s, lon_s, alt_s)[1]

    # --- velocities --------------------------------------------------------------------
    def velocity_to_enu(self, x, y, z, vx, vy, vz=None, geodetic=None):
        """Frame velocity at frame position (x, y, z) → local (east, north, up) m/s at the
        target's own geodetic position — what a published Track carries. ``geodetic``:
        ``to_geodetic(x, y, z)`` if the caller has it already (not computed again).

        ``planar``: identity; ``ned``: rotation from the reference ENU to the target's ENU;
        ``stereographic``: inverse of the local plane Jacobian (analytic, from PROJ's factors)."""
        x, y, z, vx, vy = np.broadcast_arrays(*(np.asarray(a, float) for a in (x, y, z, vx, vy)))
        vz = np.zeros_like(vx) if vz is None else np.broadcast_to(np.asarray(vz, float), vx.shape)
        if self.kind is FrameKind.PLANAR:
            return vx.copy(), vy.copy(), np.array(vz, copy=True)
        lat, lon, alt = self.to_geodetic(x, y, z) if geodetic is None else geodetic
        if self.kind is FrameKind.NED:
            rot = enu_to_enu_rotation(self.lat0, self.lon0, lat, lon)
            v = np.einsum("...ij,...j->...i", rot, np.stack([vx, vy, vz], axis=-1))
            return v[..., 0], v[..., 1], v[..., 2]
        # J = [[a, b, 0], [c, d, 0], [0, 0, 1]] (local_plane_jacobian): J⁻¹ v by the
        # 2 × 2 closed form, the vertical component unchanged
        J = self.local_plane_jacobian(lat, lon, alt)
        a, b, c, d = (J[:, i, j].reshape(np.shape(vx)) for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)))
        det = a * d - b * c
        return (d * vx - b * vy) / det, (a * vy - c * vx) / det, np.array(vz, dtype=float)

    def local_plane_jacobian(self, lat, lon, alt) -> np.ndarray:
        """∂(x, y, z)/∂(e, n, u) of the frame map at geodetic points, with (e, n, u) the
        local ENU at each point itself, shape (m, 3, 3).

        ``stereographic``/``planar`` (analytic): a step de east at height h moves the
        longitude by de/((N + h) cos φ), a step dn north the latitude by dn/(M + h), and
        PROJ's partial derivatives of the projection (``Proj.get_factors``: ∂x/∂λ, ∂x/∂φ,
        ∂y/∂λ, ∂y/∂φ, per radian on the unit-axis ellipsoid, hence the factor a) give
        the plane step — the grid-convergence rotation times the point scale, reduced
        to height h. A step along the normal changes neither latitude nor longitude and
        the height changes by du, so the z row and column are (0, 0, 1).
        ``ned``: the rotation from the point's ENU to the reference ENU (exact)."""
        lat, lon, alt = (np.ravel(np.asarray(a, float)) for a in (lat, lon, alt))
        m = lat.size
        if self.kind is FrameKind.NED:
            return np.broadcast_to(
                enu_to_enu_rotation(lat, lon, self.lat0, self.lon0), (m, 3, 3)
            ).copy()
        f = _plane_proj(self.lat0, self.lon0).get_factors(lon, lat)
        de = WGS84_A / ((prime_vertical_radius(lat) + alt) * np.cos(np.radians(lat)))
        dn = WGS84_A / (meridian_radius(lat) + alt)
        J = np.zeros((m, 3, 3))
        J[:, 0, 0] = np.asarray(f.dx_dlam) * de
        J[:, 0, 1] = np.asarray(f.dx_dphi) * dn
        J[:, 1, 0] = np.asarray(f.dy_dlam) * de
        J[:, 1, 1] = np.asarray(f.dy_dphi) * dn
        J[:, 2, 2] = 1.0
        return J


@functools.lru_cache(maxsize=1024)
def _site_position(frame: SystemFrame, lat: float, lon: float, alt: float) -> np.ndarray:
    """:meth:`SystemFrame.site_position`, cached by (frame spec, site): frames compare
    and hash by their spec, so equal frames share the entry."""
    return np.array([float(v) for v in frame.from_geodetic(lat, lon, alt)])
