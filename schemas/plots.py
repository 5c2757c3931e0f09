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
from pydantic import Field, PrivateAttr, model_validator

from . import columns as col
from .base import INT64_MAX, Int64, NonNegInt64, WireModel
from .keys import ID_PATTERN

_FLOAT_COLUMNS = ("range", "azimuth", "elevation", "altitude", "x", "y", "doppler", "amplitude")
OPTIONAL_PLOT_COLUMNS = (*_FLOAT_COLUMNS, "mode_s", "mode_3a", "target_id")
"""The per-plot columns of a ``PlotBatch`` that may be absent (``None``); ``time`` is not."""
_ALL_COLUMNS = ("time", *OPTIONAL_PLOT_COLUMNS)
_RANGES = (  # column, lower bound, upper bound, upper bound open, null allowed, unit
    ("range", 0.0, None, False, False, "m"),
    ("azimuth", 0.0, 2 * math.pi, True, False, "rad"),
    ("elevation", -math.pi / 2, math.pi / 2, False, True, "rad"),
    ("altitude", -1_000.0, 100_000.0, False, True, "m"),
)


class _ColumnArrays(dict):
    """Cache of a batch's columns as arrays: not part of the batch's value, so any two
    caches compare equal (batches compare by their fields only)."""

    def __eq__(self, other: object) -> bool:
        return other is None or isinstance(other, _ColumnArrays)

    __hash__ = None


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

    _arrays: _ColumnArrays | None = PrivateAttr(None)
    """The columns as read-only NumPy arrays, built once by the validator (or on the
    first :meth:`column` call), each with the list it was built from: an entry is used
    only while the field still holds that very list (a copy with an updated field, or
    a field assigned afterwards, builds its array anew). A plain default (no factory):
    pydantic creates private defaults on every validation, a factory costs ≈ 10 µs."""

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
        self._check_time()
        for name, lo, hi, hi_open, allow_nan, unit in _RANGES:
            if getattr(self, name) is not None:
                self._keep(name, col.check_range(name, getattr(self, name), lo, hi,
                                                 hi_open=hi_open, allow_nan=allow_nan,
                                                 unit=unit))  # fmt: skip
        for name, allow_nan in (("x", False), ("y", False), ("doppler", True), ("amplitude", True)):
            if getattr(self, name) is not None:
                self._keep(name, col.as_float_array(name, getattr(self, name), allow_nan=allow_nan))
        for name, hi in (("mode_s", 0xFFFFFF), ("mode_3a", 0o7777)):
            if getattr(self, name) is not None:
                col.check_codes(name, getattr(self, name), hi)
        return self

    def _check_time(self) -> None:
        """Times ≥ 0 ns and non-decreasing (one comparison when they are)."""
        times = self._keep("time", np.asarray(self.time, dtype=np.int64))
        if times[0] >= 0 and (times[1:] >= times[:-1]).all():
            return
        if (times < 0).any():
            i = int(np.flatnonzero(times < 0)[0])
            raise ValueError(f"time[{i}] = {int(times[i])}: must be >= 0 ns")
        col.check_non_decreasing("time", self.time)

    def _keep(self, name: str, arr: np.ndarray) -> np.ndarray:
        """Store ``arr`` (read-only) as the array of column ``name``; return it. (The
        private dict is read directly: attribute access to a private goes through
        pydantic's ``__getattr__``, ≈ 30 times slower.)"""
        arr.flags.writeable = False
        private = self.__pydantic_private__
        if private.get("_arrays") is None:
            private["_arrays"] = _ColumnArrays()
        private["_arrays"][name] = (getattr(self, name), arr)
        return arr

    # --- NumPy views -------------------------------------------------------------------
    def column(self, name: str) -> np.ndarray | None:
        """Return a column as a NumPy array (float64, int64 for time/target_id), or None.
        Optional integer columns (mode_s, mode_3a) use -1 for null, float columns NaN.
        The array is read-only and shared by every call (copy it to modify it)."""
        values = getattr(self, name)
        if values is None:
            return None
        arrays = self.__pydantic_private__.get("_arrays")
        kept = None if arrays is None else arrays.get(name)
        if kept is not None and kept[0] is values and len(kept[1]) == len(values):
            return kept[1]
        if name in ("time", "target_id"):
            arr = np.asarray(values, dtype=np.int64)
        elif name in ("mode_s", "mode_3a"):
            arr = np.asarray([-1 if v is None else v for v in values], dtype=np.int64)
        else:
            arr = np.asarray(values, dtype=np.float64)
        return self._keep(name, arr)
