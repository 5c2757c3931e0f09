"""Positions and phases of ADS-B (CAT021) and airport sensor (CAT010) reports, held as
read and placed in an evaluation frame's east/north plane when the frame is known.

* **CAT021** gives WGS-84 latitude/longitude; the height is the geometric height when
  reported, else the flight level × 30.48 m, else the frame origin's height (it moves
  the horizontal position in a local tangent plane by well under a metre within 10 km
  of the origin, and not at all in the stereographic plane).
* **CAT010** gives WGS-84 I041 when present, else Cartesian I042 (x east, y north of
  the sensor, in its local tangent plane at the site) or polar I040 (ρ, θ clockwise
  from north, x = ρ sin θ, y = ρ cos θ), both relative to the sensor's site from the
  sites file (SAC/SIC → radar id ``"SAC-SIC"``) and placed on the site's tangent plane
  (up = 0: a surface target 5 km out is 2 m below that plane, a horizontal effect of
  millimetres); :meth:`~skyfuse.fusion.frames.SystemFrame.enu_to_frame` moves them to
  the frame. A report whose sensor has no site cannot be placed (``no_site``).

**Ground / airborne** (:func:`ground_flags`): a report with the ground bit set (CAT021
I040 GBS, CAT010 I020 GBS) is on the ground. Without it, a report carrying a flight
level or a geometric height is airborne (an aircraft in the air reports its altitude;
in the LEBL recordings every report without the ground bit has a flight level), and a
report with neither is on the ground when its ground speed is below 25 m/s (≈ 50 kt,
no aircraft flies that slowly) and airborne otherwise (also without a speed). A
primary surface radar's reports (CAT010 TYP 3, PSR) are on the ground: it sees the
airport surface only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skyfuse.services.asterix import cat010, cat021
from skyfuse.services.asterix.sites import radar_id_for

FT = 0.3048
SLOW_MS = 25.0
"""Ground speed (m/s) under which a report with neither ground bit nor altitude is on
the ground."""
PSR = 3  # CAT010 I020 TYP: primary surveillance radar (an SMR)


def _num(values) -> np.ndarray:
    return np.array([np.nan if v is None else float(v) for v in values], dtype=float)


@dataclass(frozen=True)
class ReportPositions:
    """Where each report is, as read: geodetic ``lat``, ``lon``, ``height`` (NaN when the
    report gives none) or ``east``, ``north`` of the site ``site`` (radar id, ``""`` for
    geodetic rows). ``placeable`` is False for rows that have neither."""

    lat: np.ndarray
    lon: np.ndarray
    height: np.ndarray
    east: np.ndarray
    north: np.ndarray
    site: np.ndarray

    @property
    def placeable(self) -> np.ndarray:
        return np.isfinite(self.lat) | (np.isfinite(self.east) & (self.site != ""))

    def take(self, rows: np.ndarray) -> ReportPositions:
        return ReportPositions(*(getattr(self, k)[rows] for k in _FIELDS))

    def in_frame(self, frame, sites: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, ok) in ``frame``'s plane (m); ``ok`` False where the row has no
        position or its site is not in ``sites`` (radar id → ``RadarSite``)."""
        n = len(self.lat)
        x, y = np.full(n, np.nan), np.full(n, np.nan)
        geo = np.isfinite(self.lat)
        if geo.any():
            h = np.where(np.isfinite(self.height[geo]), self.height[geo], frame.alt0)
            gx, gy, _ = frame.from_geodetic(self.lat[geo], self.lon[geo], h)
            x[geo], y[geo] = gx, gy
        rel = ~geo & np.isfinite(self.east)
        for sid in np.unique(self.site[rel]).tolist():
            site = sites.get(sid)
            if site is None:
                continue
            rows = np.flatnonzero(rel & (self.site == sid))
            enu = np.column_stack([self.east[rows], self.north[rows], np.zeros(len(rows))])
            p = frame.enu_to_frame(enu, site.lat, site.lon, site.alt)
            x[rows], y[rows] = p[:, 0], p[:, 1]
        ok = np.isfinite(x) & np.isfinite(y)
        return x, y, ok


_FIELDS = ("lat", "lon", "height", "east", "north", "site")


def cat021_positions(reports: list[cat021.Cat021Report]) -> ReportPositions:
    """Geodetic positions of ADS-B reports (module docstring)."""
    height = _num(r.geometric_height_m for r in reports)
    fl = _num(r.flight_level for r in reports) * 100.0 * FT
    height = np.where(np.isfinite(height), height, fl)
    n = len(reports)
    return ReportPositions(
        _num(r.lat for r in reports), _num(r.lon for r in reports), height,
        np.full(n, np.nan), np.full(n, np.nan), np.full(n, "", dtype=object),
    )  # fmt: skip


def cat010_positions(reports: list[cat010.Cat010Report]) -> ReportPositions:
    """Positions of CAT010 reports: I041, else I042, else I040 (module docstring)."""
    lat, lon = _num(r.lat for r in reports), _num(r.lon for r in reports)
    ex, ny = _num(r.x_m for r in reports), _num(r.y_m for r in reports)
    rho, theta = _num(r.rho_m for r in reports), np.radians(_num(r.theta_deg for r in reports))
    polar = ~np.isfinite(ex) & np.isfinite(rho)
    ex[polar] = rho[polar] * np.sin(theta[polar])
    ny[polar] = rho[polar] * np.cos(theta[polar])
    site = np.array([radar_id_for(r.sac, r.sic) for r in reports], dtype=object)
    height = _num(r.height_m for r in reports)
    fl = _num(r.flight_level for r in reports) * 100.0 * FT
    return ReportPositions(lat, lon, np.where(np.isfinite(height), height, fl), ex, ny, site)


def ground_flags(reports) -> np.ndarray:
    """(n,) bool: each CAT010/CAT021 report is on the ground (module docstring)."""
    out = np.zeros(len(reports), bool)
    for i, r in enumerate(reports):
        if r.ground or getattr(r, "typ", None) == PSR:
            out[i] = True
            continue
        heights = (getattr(r, "geometric_height_m", None), getattr(r, "height_m", None))
        if r.flight_level is not None or any(h is not None for h in heights):
            continue
        speed = r.ground_speed_ms
        if speed is None and getattr(r, "vx_ms", None) is not None and r.vy_ms is not None:
            speed = float(np.hypot(r.vx_ms, r.vy_ms))
        out[i] = speed is not None and speed < SLOW_MS
    return out
