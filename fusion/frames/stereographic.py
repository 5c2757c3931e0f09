"""The stereographic system plane ([Dikić]; Mulholland & Stout 1982).

Oblique conformal stereographic projection of the WGS-84 ellipsoid (double projection
via the Gaussian conformal sphere), PROJ's ``+proj=sterea`` with ``k_0 = 1`` — the
FAA/NAS system-plane procedure. x is east and y north, in metres, tangent at the
system centre (lat0, lon0). Altitude is carried separately as height above the
ellipsoid.
"""

from __future__ import annotations

import numpy as np
from pyproj import CRS, Transformer


class Stereographic:
    """Forward/inverse stereographic projection centred at (lat0_deg, lon0_deg).

    >>> s = Stereographic(44.8, 20.45)
    >>> x, y = s.forward(44.9, 20.6)      # metres east, north
    >>> lat, lon = s.inverse(x, y)        # degrees
    """

    def __init__(self, lat0_deg: float, lon0_deg: float) -> None:
        if not -90.0 < lat0_deg < 90.0:
            raise ValueError(f"lat0_deg = {lat0_deg}: must be strictly between -90 and 90")
        if not -180.0 <= lon0_deg <= 180.0:
            raise ValueError(f"lon0_deg = {lon0_deg}: must be in [-180, 180]")
        self.lat0 = float(lat0_deg)
        self.lon0 = float(lon0_deg)
        self.crs = CRS.from_proj4(
            f"+proj=sterea +lat_0={self.lat0!r} +lon_0={self.lon0!r} +k_0=1 "
            "+x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs"
        )
        geodetic = CRS.from_epsg(4326)
        self._fwd = Transformer.from_crs(geodetic, self.crs, always_xy=True)
        self._inv = Transformer.from_crs(self.crs, geodetic, always_xy=True)

    def forward(self, lat_deg, lon_deg) -> tuple[np.ndarray, np.ndarray]:
        """Geodetic latitude/longitude (degrees) → plane (x east, y north), metres."""
        x, y = self._fwd.transform(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
        return np.asarray(x), np.asarray(y)

    def inverse(self, x_east_m, y_north_m) -> tuple[np.ndarray, np.ndarray]:
        """Plane (x east, y north), metres → geodetic latitude/longitude, degrees."""
        lon, lat = self._inv.transform(np.asarray(x_east_m, float), np.asarray(y_north_m, float))
        return np.asarray(lat), np.asarray(lon)

    def __repr__(self) -> str:
        return f"Stereographic(lat0_deg={self.lat0}, lon0_deg={self.lon0})"
