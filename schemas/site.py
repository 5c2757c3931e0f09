"""``RadarSite``: where a radar is and how it measures.

Published once on ``skyfuse/@v1/radar/{id}/site`` (and again whenever it changes);
the fusion service needs it to convert that radar's plots into the system frame.
"""

from __future__ import annotations

import math
from enum import StrEnum

from pydantic import Field, field_validator, model_validator

from .base import WireModel
from .keys import ID_PATTERN


class RadarKind(StrEnum):
    """``2d``: range and azimuth, altitude from Mode C / flight level;
    ``3d``: range, azimuth and elevation;
    ``cartesian``: a planar test sensor measuring (x east, y north) in metres in the
    site's local plane, with ``R = sigma_cartesian² I`` ([thesis] §7.3)."""

    TWO_D = "2d"
    THREE_D = "3d"
    CARTESIAN = "cartesian"


class RadarSite(WireModel):
    """A radar's position, kind and accuracy. Angles in radians, lengths in metres."""

    radar_id: str = Field(pattern=ID_PATTERN, description="Radar id, one key chunk")
    name: str = Field("", description="Human-readable name")
    lat: float = Field(ge=-90.0, le=90.0, description="Site latitude, WGS-84, degrees")
    lon: float = Field(ge=-180.0, le=180.0, description="Site longitude, WGS-84, degrees")
    alt: float = Field(
        0.0, ge=-500.0, le=10_000.0, description="Antenna height above the WGS-84 ellipsoid, m"
    )
    kind: RadarKind = Field(description="Measurement kind: 2d, 3d or cartesian")
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
        description="Per-axis position noise standard deviation (cartesian only), m",
    )
    scan_period: float = Field(4.0, gt=0.0, le=600.0, description="Antenna revolution period, s")
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

    @model_validator(mode="after")
    def _range_interval(self) -> RadarSite:
        if self.min_range >= self.max_range:
            raise ValueError(
                f"min_range = {self.min_range} m must be smaller than max_range = "
                f"{self.max_range} m"
            )
        return self
