"""``PlotBatch``: the plots of one radar sector (or one full scan), columnar.

One message carries many plots as parallel columns, one list per field, because a
message per plot is far too slow (stack-notes: serialisation dominates). Column i of
every present field describes plot i.

Geometry is either polar (``range`` + ``azimuth``, with ``elevation`` for 3-D radars
or ``altitude`` for 2-D radars) or planar (``x`` + ``y`` for the cartesian test sensor).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, model_validator

from . import columns as col
from .base import INT64_MAX, Int64, NonNegInt64, WireModel
from .keys import ID_PATTERN

_FLOAT_COLUMNS = ("range", "azimuth", "elevation", "altitude", "x", "y", "doppler", "amplitude")
_ALL_COLUMNS = ("time", *_FLOAT_COLUMNS, "mode_s", "mode_3a", "target_id")


class PlotBatch(WireModel):
    """Plots of one radar sector sweep. Times in integer nanoseconds since the Unix epoch
    (UTC); ranges in metres; angles in radians, azimuth clockwise from true north at the
    site, elevation above the local horizontal."""

    radar_id: str = Field(pattern=ID_PATTERN, description="Radar id (matches the RadarSite)")
    scan: int = Field(ge=0, le=INT64_MAX, description="Antenna revolution number, from 0")
    seq: int = Field(
        ge=0, le=INT64_MAX, description="Batch sequence number from this radar, +1 per batch"
    )
    epoch: int = Field(
        0,
        ge=0,
        le=INT64_MAX,
        description="Epoch of the sensor's numbering: within one epoch a seq is never given "
        "to two batches, so (radar_id, epoch, seq) identifies a batch and a repeat is a "
        "duplicate; 0 = not announced (recordings from before the field)",
    )
    sector_start: float = Field(
        0.0,
        ge=0.0,
        lt=2 * math.pi,
        description="Azimuth where the sector sweep starts, rad clockwise from north",
    )
    sector_width: float = Field(
        2 * math.pi,
        gt=0.0,
        le=2 * math.pi,
        description="Azimuth extent of the sector swept clockwise from sector_start, rad",
    )
    time_start: int = Field(
        ge=0, le=INT64_MAX, description="Time the beam entered the sector, ns UTC"
    )
    time_end: int = Field(ge=0, le=INT64_MAX, description="Time the beam left the sector, ns UTC")

    time: list[NonNegInt64] = Field(
        default_factory=list, description="Plot times, ns UTC, non-decreasing"
    )
    range: list[float] | None = Field(None, description="Slant range, m, >= 0")
    azimuth: list[float] | None = Field(
        None, description="Azimuth, rad, clockwise from true north, in [0, 2π)"
    )
    elevation: list[float | None] | None = Field(
        None, description="Elevation (3-D radars), rad in [-π/2, π/2]; null = not measured"
    )
    altitude: list[float | None] | None = Field(
        None,
        description="Target altitude from flight level/Mode C (2-D radars), m; null = unknown",
    )
    x: list[float] | None = Field(None, description="Cartesian sensor: east, m, site plane")
    y: list[float] | None = Field(None, description="Cartesian sensor: north, m, site plane")
    doppler: list[float | None] | None = Field(
        None, description="Radial velocity, m/s, positive receding; null = not measured"
    )
    amplitude: list[float | None] | None = Field(
        None, description="Plot amplitude, dB; null = not measured"
    )
    mode_s: list[int | None] | None = Field(
        None, description="Mode-S 24-bit ICAO address, null if none (never used to associate)"
    )
    mode_3a: list[int | None] | None = Field(
        None, description="Mode-3/A code as an integer 0..4095 (octal 0000-7777), null if none"
    )
    target_id: list[Int64] | None = Field(
        None,
        description="Simulation only: originating target id, -1 for clutter "
        "(for evaluation; never used by the tracker)",
    )

    def __len__(self) -> int:
        return len(self.time)

    @property
    def is_cartesian(self) -> bool:
        return self.x is not None

    @model_validator(mode="after")
    def _check_columns(self) -> PlotBatch:
        if self.time_end < self.time_start:
            raise ValueError(
                f"time_end = {self.time_end} is earlier than time_start = {self.time_start}"
            )
        n = col.check_equal_lengths({k: getattr(self, k) for k in _ALL_COLUMNS})
        if len(self.time) != n:
            raise ValueError(f"column 'time' has {len(self.time)} values but the batch has {n}")
        polar = self.range is not None or self.azimuth is not None
        planar = self.x is not None or self.y is not None
        if polar and planar:
            raise ValueError("a batch carries either range/azimuth or x/y columns, not both")
        if n > 0 and not (polar or planar):
            raise ValueError("plots need range and azimuth (radar) or x and y (cartesian sensor)")
        if polar and (self.range is None or self.azimuth is None):
            missing = "range" if self.range is None else "azimuth"
            raise ValueError(f"column {missing!r} is missing: polar plots need range and azimuth")
        if planar and (self.x is None or self.y is None):
            missing = "x" if self.x is None else "y"
            raise ValueError(f"column {missing!r} is missing: cartesian plots need x and y")
        if n == 0:
            return self
        times = np.asarray(self.time, dtype=np.int64)
        if (times < 0).any():
            i = int(np.flatnonzero(times < 0)[0])
            raise ValueError(f"time[{i}] = {int(times[i])}: must be >= 0 ns")
        col.check_non_decreasing("time", self.time)
        if self.range is not None:
            col.check_range("range", self.range, 0.0, unit="m")
        if self.azimuth is not None:
            col.check_range("azimuth", self.azimuth, 0.0, 2 * math.pi, hi_open=True, unit="rad")
        if self.elevation is not None:
            col.check_range(
                "elevation", self.elevation, -math.pi / 2, math.pi / 2, allow_nan=True, unit="rad"
            )
        if self.altitude is not None:
            col.check_range(
                "altitude", self.altitude, -1_000.0, 100_000.0, allow_nan=True, unit="m"
            )
        for name in ("x", "y"):
            if getattr(self, name) is not None:
                col.as_float_array(name, getattr(self, name))
        for name in ("doppler", "amplitude"):
            if getattr(self, name) is not None:
                col.as_float_array(name, getattr(self, name), allow_nan=True)
        for name, hi in (("mode_s", 0xFFFFFF), ("mode_3a", 0o7777)):
            values = getattr(self, name)
            if values is None:
                continue
            for i, v in enumerate(values):
                if v is not None and not 0 <= v <= hi:
                    raise ValueError(f"{name}[{i}] = {v}: must be in 0..{hi}")
        return self

    # --- NumPy views -------------------------------------------------------------------
    def column(self, name: str) -> np.ndarray | None:
        """Return a column as a NumPy array (float64, int64 for time/target_id), or None.
        Optional integer columns (mode_s, mode_3a) use -1 for null, float columns NaN."""
        values = getattr(self, name)
        if values is None:
            return None
        if name in ("time", "target_id"):
            return np.asarray(values, dtype=np.int64)
        if name in ("mode_s", "mode_3a"):
            return np.asarray([-1 if v is None else v for v in values], dtype=np.int64)
        return np.asarray(values, dtype=np.float64)
