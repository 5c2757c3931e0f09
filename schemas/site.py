"""``RadarSite``: where a sensor is and how it measures.

Published once on ``skyfuse/@v1/radar/{id}/site`` (and again whenever it changes);
the fusion service needs it to convert that sensor's plots into the system frame.

A "site" is any sensor, not only a rotating radar (the key space keeps the name
``radar/{id}``). What distinguishes the kinds:

* the **geometry** of a plot (``kind``): polar ``2d``/``3d`` (a rotating radar, or a
  surface movement radar whose plots carry the surface height), ``cartesian`` (x east,
  y north in the site's local plane: a multilateration system's positions relative to
  its reference point, or a test sensor) or ``wgs84`` (latitude/longitude: ADS-B);
* the **detection semantics** (``detection``): ``sweep`` — the sensor looks at every
  target in its coverage each scan, so a track it did not detect is a missed detection
  (a radar, a surface movement radar); ``reports`` — the sensor reports the targets it
  tracks at its own rate (ADS-B, multilateration), so its silence about a track counts
  as a miss only if it has reported that track within ``report_timeout`` seconds (an
  aircraft without a transponder is never reported by them, and that is no evidence
  that it does not exist);
* the **coverage**: a range ring (``min_range``/``max_range``), optionally a polygon
  of WGS-84 vertices (``coverage``) and a ceiling (``max_altitude``: a surface
  movement radar sees the airport surface, not aircraft at altitude).
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import Literal

from pydantic import Field, field_validator, model_validator

from .base import WireModel
from .keys import ID_PATTERN


class RadarKind(StrEnum):
    """The geometry of a sensor's plots. ``2d``: range and azimuth, altitude from Mode C
    / flight level (or the surface height of a surface movement radar's plots);
    ``3d``: range, azimuth and elevation;
    ``cartesian``: (x east, y north) in metres in the site's local tangent plane, with
    ``R = σ² I``, σ the plot's ``sigma`` or ``sigma_cartesian`` (a multilateration
    system relative to its reference point; the planar test sensor of [thesis] §7.3);
    ``wgs84``: latitude and longitude (ADS-B), σ per axis from the plot's ``sigma`` or
    ``sigma_cartesian``."""

    TWO_D = "2d"
    THREE_D = "3d"
    CARTESIAN = "cartesian"
    WGS84 = "wgs84"


class Detection(StrEnum):
    """What a sensor's silence about a track means (module docstring): ``sweep`` — a
    missed detection wherever the sensor could have seen the track; ``reports`` — a miss
    only for tracks the sensor reported within its ``report_timeout``."""

    SWEEP = "sweep"
    REPORTS = "reports"


MAX_COVERAGE_VERTICES = 1000


class RadarSite(WireModel):
    """A radar's position, kind and accuracy. Angles in radians, lengths in metres."""

    radar_id: str = Field(pattern=ID_PATTERN, description="Radar id, one key chunk")
    name: str = Field("", description="Human-readable name")
    lat: float = Field(ge=-90.0, le=90.0, description="Site latitude, WGS-84, degrees")
    lon: float = Field(ge=-180.0, le=180.0, description="Site longitude, WGS-84, degrees")
    alt: float = Field(
        0.0, ge=-500.0, le=10_000.0, description="Antenna height above the WGS-84 ellipsoid, m"
    )
    kind: RadarKind = Field(
        RadarKind.TWO_D,
        description="Plot geometry: 2d, 3d (polar), cartesian (x east, y north of the site) "
        "or wgs84 (latitude/longitude)",
    )
    detection: Detection = Field(
        Detection.SWEEP,
        description="sweep: every track in coverage is looked at each scan (radar, surface "
        "movement radar); reports: the sensor reports the targets it tracks (ADS-B, "
        "multilateration): a track it has not reported within report_timeout is not missed",
    )
    timing: Literal["sweep", "plots"] = Field(
        "sweep",
        description="Polar sensors: sweep — a batch's plots were swept across its sector from "
        "time_start to time_end, each track is predicted to the time the beam crossed it; "
        "plots — to the time of the batch plot nearest to it (a surface movement radar whose "
        "revolutions start at an unknown azimuth). Report-based sensors always use plots",
    )
    report_timeout: float = Field(
        10.0,
        gt=0.0,
        le=600.0,
        description="detection = reports: a track this sensor reported within this many "
        "seconds is expected in its next reports (P_D applies), s",
    )
    coverage: list[tuple[float, float]] | None = Field(
        None,
        description="Coverage polygon: WGS-84 vertices [lat, lon] in degrees (at least 3, in "
        "order; closed implicitly); null: the range ring alone",
    )
    max_altitude: float | None = Field(
        None,
        ge=-500.0,
        le=100_000.0,
        description="Ceiling of the coverage, m above the ellipsoid (a surface movement radar "
        "sees the surface only); null: none",
    )
    sigma_range: float = Field(
        50.0, gt=0.0, le=10_000.0, description="Slant-range noise standard deviation, m"
    )
    sigma_azimuth: float = Field(
        0.002, gt=0.0, le=0.5, description="Azimuth noise standard deviation, rad"
    )
    sigma_elevation: float = Field(
        0.004, gt=0.0, le=0.5, description="Elevation noise standard deviation (3d only), rad"
    )
    sigma_altitude: float = Field(
        30.0,
        gt=0.0,
        le=10_000.0,
        description="Altitude (flight level) noise standard deviation (2d only), m",
    )
    sigma_cartesian: float = Field(
        5.0,
        gt=0.0,
        le=10_000.0,
        description="Per-axis horizontal position noise standard deviation (cartesian and "
        "wgs84, unless a plot carries its own sigma), m",
    )
    sigma_growth: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="Cartesian sensors, plots without their own sigma: the per-axis σ grows "
        "with the distance ρ from the site as √(sigma_cartesian² + (sigma_growth · ρ)²), m "
        "per m (a multilateration system's geometry degrades away from its receivers)",
    )
    scan_period: float = Field(
        4.0, gt=0.0, le=600.0, description="Antenna revolution (or report cycle) period, s"
    )
    p_detection: float = Field(0.9, gt=0.0, le=1.0, description="Nominal detection probability")
    min_range: float = Field(0.0, ge=0.0, description="Minimum instrumented range, m")
    max_range: float = Field(
        250_000.0, gt=0.0, le=2_000_000.0, description="Maximum instrumented range, m"
    )
    clutter_density: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="Nominal false-plot density over the coverage, plots per m² per scan",
    )
    n_sectors: int = Field(
        16, ge=1, le=360, description="Sector batches published per antenna revolution"
    )

    @field_validator("lat", "lon", "alt")
    @classmethod
    def _finite(cls, v: float) -> float:
        if not math.isfinite(v):
            raise ValueError(f"value {v!r} is not finite")
        return v

    @field_validator("coverage")
    @classmethod
    def _polygon(cls, v):
        if v is None:
            return v
        if not 3 <= len(v) <= MAX_COVERAGE_VERTICES:
            raise ValueError(
                f"coverage has {len(v)} vertices: a polygon needs 3..{MAX_COVERAGE_VERTICES}"
            )
        for i, (lat, lon) in enumerate(v):
            if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
                raise ValueError(f"coverage[{i}] latitude = {lat!r}: must be in [-90, 90] deg")
            if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
                raise ValueError(f"coverage[{i}] longitude = {lon!r}: must be in [-180, 180] deg")
        return v

    @model_validator(mode="after")
    def _range_interval(self) -> RadarSite:
        if self.min_range >= self.max_range:
            raise ValueError(
                f"min_range = {self.min_range} m must be smaller than max_range = "
                f"{self.max_range} m"
            )
        return self
