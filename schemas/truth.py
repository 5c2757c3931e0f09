"""``Truth``: simulated ground truth of all targets alive at one instant, columnar."""

from __future__ import annotations

from pydantic import Field, model_validator

from . import columns as col
from .base import INT64_MAX, Int64, WireModel
from .keys import ID_PATTERN

_COLUMNS = ("target_id", "lat", "lon", "alt", "vel_east", "vel_north", "vel_up", "x", "y")


class RadarBias(WireModel):
    """The systematic errors a simulated radar applies (reported = (1 + range_gain) ×
    true range + range, azimuth + azimuth, time + time): the truth a registration
    estimate is scored against."""

    radar_id: str = Field(pattern=ID_PATTERN, description="Radar id")
    azimuth: float = Field(0.0, description="Azimuth offset, rad clockwise")
    range: float = Field(0.0, description="Range offset, m")
    range_gain: float = Field(0.0, gt=-0.5, lt=0.5, description="Range gain error, 1")
    time: float = Field(0.0, description="Time-stamping offset, s")


class Truth(WireModel):
    """Positions and velocities of the simulated targets at ``time``.

    ``x``/``y`` are given for planar scenarios: metres east/north in the scenario plane,
    the frame the planar (thesis) scenarios are defined in."""

    time: int = Field(ge=0, le=INT64_MAX, description="Time, ns UTC")
    target_id: list[Int64] = Field(default_factory=list, description="Target ids")
    lat: list[float] = Field(default_factory=list, description="Latitude, WGS-84, degrees")
    lon: list[float] = Field(default_factory=list, description="Longitude, WGS-84, degrees")
    alt: list[float] = Field(default_factory=list, description="Height above the ellipsoid, m")
    vel_east: list[float] = Field(default_factory=list, description="Velocity east, m/s")
    vel_north: list[float] = Field(default_factory=list, description="Velocity north, m/s")
    vel_up: list[float] = Field(default_factory=list, description="Velocity up, m/s")
    x: list[float] | None = Field(None, description="Planar scenarios: east, m, scenario plane")
    y: list[float] | None = Field(None, description="Planar scenarios: north, m, scenario plane")
    radar_bias: list[RadarBias] = Field(
        default_factory=list, description="Simulated radars' systematic errors (biased ones)"
    )

    @model_validator(mode="after")
    def _check(self) -> Truth:
        col.check_equal_lengths({k: getattr(self, k) for k in _COLUMNS})
        col.check_range("lat", self.lat, -90.0, 90.0, unit="deg")
        col.check_range("lon", self.lon, -180.0, 180.0, unit="deg")
        for k in ("alt", "vel_east", "vel_north", "vel_up", "x", "y"):
            if getattr(self, k) is not None:
                col.as_float_array(k, getattr(self, k))
        if len(set(self.target_id)) != len(self.target_id):
            raise ValueError("target_id values must be unique within one Truth message")
        return self
