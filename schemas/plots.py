"""``PlotBatch``: the plots of one radar sector (or one full scan), columnar.

One message carries many plots as parallel columns, one list per field, because a
message per plot is far too slow (stack-notes: serialisation dominates). Column i of
every present field describes plot i.

Geometry is polar (``range`` + ``azimuth``, with ``elevation`` for 3-D radars or
``altitude`` for 2-D radars), planar (``x`` + ``y``: a cartesian sensor's plane, e.g.
multilateration relative to its reference point) or geodetic (``lat`` + ``lon``:
ADS-B), as the site's ``kind`` says. Report-based sensors may give each plot its own
horizontal accuracy (``sigma``, m per axis: an ADS-B NACp/NUCp, a multilateration
I500) and a reported velocity (``v_east``, ``v_north`` with ``sigma_velocity``).

Secondary-surveillance columns (:mod:`schemas.identity`: names, units, bounds): the
identity of the reply (``mode_3a`` with its flags, ``mode_s``, ``callsign``,
``flight_level`` with its flags, ``spi``, ``flight_status``) and the downlinked aircraft
parameters (``selected_altitude_mcp`` … ``inertial_vertical_rate``). All optional: an
absent column costs nothing, an absent flag column means "not set" for every plot
(recordings from before the flags carried validated, ungarbled codes only).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, PrivateAttr, model_validator

from . import columns as col
from . import identity as ident
from .base import INT64_MAX, Int64, NonNegInt64, WireModel
from .keys import ID_PATTERN

_FLOAT_COLUMNS = (
    "range", "azimuth", "elevation", "altitude", "x", "y", "lat", "lon", "sigma",
    "v_east", "v_north", "sigma_velocity", "doppler", "amplitude",
)  # fmt: skip
FLAG_COLUMNS = (
    "mode_3a_not_validated", "mode_3a_garbled", "mode_3a_smoothed",
    "flight_level_not_validated", "flight_level_garbled", "spi",
)  # fmt: skip
"""Boolean columns: null (or an absent column) means false."""
_CODE_COLUMNS = (  # integer columns: null → -1 in :meth:`PlotBatch.column`
    ("mode_s", ident.MODE_S_MAX), ("mode_3a", ident.MODE_3A_MAX),
    ("flight_status", ident.FLIGHT_STATUS_MAX),
)  # fmt: skip
IDENTITY_COLUMNS = (
    "mode_3a", *FLAG_COLUMNS[:3], "mode_s", "callsign", "flight_level", *FLAG_COLUMNS[3:],
    "flight_status", *(q.name for q in ident.DOWNLINKED),
)  # fmt: skip
"""The secondary-surveillance columns (:mod:`schemas.identity`)."""
OPTIONAL_PLOT_COLUMNS = (*_FLOAT_COLUMNS, *IDENTITY_COLUMNS, "target_id")
"""The per-plot columns of a ``PlotBatch`` that may be absent (``None``); ``time`` is not."""
_ALL_COLUMNS = ("time", *OPTIONAL_PLOT_COLUMNS)
_SSR_RANGES = (  # column, lower bound, upper bound, upper bound open, unit (null allowed)
    ("flight_level", ident.FLIGHT_LEVEL_MIN, ident.FLIGHT_LEVEL_MAX, False, "FL"),
    *((q.name, q.lo, q.hi, q.hi_open, q.unit) for q in ident.DOWNLINKED),
)
_INT_COLUMNS = frozenset(("time", "target_id", *(name for name, _ in _CODE_COLUMNS)))
_RANGES = (  # column, lower bound, upper bound, upper bound open, null allowed, unit
    ("range", 0.0, None, False, False, "m"),
    ("azimuth", 0.0, 2 * math.pi, True, False, "rad"),
    ("elevation", -math.pi / 2, math.pi / 2, False, True, "rad"),
    ("altitude", -1_000.0, 100_000.0, False, True, "m"),
    ("lat", -90.0, 90.0, False, False, "deg"),
    ("lon", -180.0, 180.0, False, False, "deg"),
    ("sigma", 0.01, 100_000.0, False, True, "m"),
    ("v_east", -2_000.0, 2_000.0, False, True, "m/s"),
    ("v_north", -2_000.0, 2_000.0, False, True, "m/s"),
    ("sigma_velocity", 0.001, 1_000.0, False, True, "m/s"),
)


def _downlinked(name: str):
    q = ident.DOWNLINKED_BY_NAME[name]
    return Field(None, description=f"{q.description}; null if not downlinked")


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
    lat: list[float] | None = Field(
        None, description="WGS-84 sensor (ADS-B): latitude, degrees in [-90, 90]"
    )
    lon: list[float] | None = Field(
        None, description="WGS-84 sensor (ADS-B): longitude, degrees in [-180, 180]"
    )
    sigma: list[float | None] | None = Field(
        None,
        description="Horizontal position σ per axis of each plot, m (> 0; e.g. from ADS-B "
        "NACp/NUCp or multilateration I500); null: the site's",
    )
    v_east: list[float | None] | None = Field(
        None, description="Reported ground velocity, east, m/s; null = not reported"
    )
    v_north: list[float | None] | None = Field(
        None, description="Reported ground velocity, north, m/s; null = not reported"
    )
    sigma_velocity: list[float | None] | None = Field(
        None, description="σ per axis of the reported velocity, m/s; null = unknown"
    )
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
    mode_3a_not_validated: list[bool | None] | None = Field(
        None, description="Mode-3/A code not validated (I048/070 V); null/absent = false"
    )
    mode_3a_garbled: list[bool | None] | None = Field(
        None, description="Mode-3/A code garbled (I048/070 G); null/absent = false"
    )
    mode_3a_smoothed: list[bool | None] | None = Field(
        None,
        description="Mode-3/A code not extracted in this scan, kept from the last one "
        "(I048/070 L); null/absent = false",
    )
    callsign: list[str | None] | None = Field(
        None,
        description="Aircraft identification (BDS 2,0 / I048/240): 1-8 characters A-Z, 0-9 "
        "and inner spaces, no padding; null if none",
    )
    flight_level: list[float | None] | None = Field(
        None,
        description="Flight level as replied (Mode C, I048/090), FL (pressure altitude / "
        "100 ft, not a height; see schemas.identity), whatever its flags; null if none",
    )
    flight_level_not_validated: list[bool | None] | None = Field(
        None, description="Flight level not validated (I048/090 V); null/absent = false"
    )
    flight_level_garbled: list[bool | None] | None = Field(
        None, description="Flight level garbled (I048/090 G); null/absent = false"
    )
    spi: list[bool | None] | None = Field(
        None, description="Special position identification (I048/020 SPI); null/absent = false"
    )
    flight_status: list[int | None] | None = Field(
        None,
        description="Mode S flight status 0..7 (I048/230 STAT: 0 airborne, 1 on ground, "
        "2/3 alert airborne/on ground, 4 alert + SPI, 5 SPI, 7 unknown); null if none",
    )
    selected_altitude_mcp: list[float | None] | None = _downlinked("selected_altitude_mcp")
    selected_altitude_fms: list[float | None] | None = _downlinked("selected_altitude_fms")
    roll_angle: list[float | None] | None = _downlinked("roll_angle")
    true_track: list[float | None] | None = _downlinked("true_track")
    ground_speed: list[float | None] | None = _downlinked("ground_speed")
    track_angle_rate: list[float | None] | None = _downlinked("track_angle_rate")
    true_airspeed: list[float | None] | None = _downlinked("true_airspeed")
    magnetic_heading: list[float | None] | None = _downlinked("magnetic_heading")
    indicated_airspeed: list[float | None] | None = _downlinked("indicated_airspeed")
    mach: list[float | None] | None = _downlinked("mach")
    baro_vertical_rate: list[float | None] | None = _downlinked("baro_vertical_rate")
    inertial_vertical_rate: list[float | None] | None = _downlinked("inertial_vertical_rate")
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

    @property
    def is_geodetic(self) -> bool:
        return self.lat is not None

    @model_validator(mode="after")
    def _check_columns(self) -> PlotBatch:
        if self.time_end < self.time_start:
            raise ValueError(
                f"time_end = {self.time_end} is earlier than time_start = {self.time_start}"
            )
        n = col.check_equal_lengths({k: getattr(self, k) for k in _ALL_COLUMNS})
        if len(self.time) != n:
            raise ValueError(f"column 'time' has {len(self.time)} values but the batch has {n}")
        self._check_geometry(n)
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
        for name, hi in _CODE_COLUMNS:
            if getattr(self, name) is not None:
                col.check_codes(name, getattr(self, name), hi)
        self._check_secondary()
        return self

    def _check_geometry(self, n: int) -> None:
        """One geometry: range/azimuth, x/y or lat/lon, each pair complete."""
        pairs = (("range", "azimuth", "polar plots"), ("x", "y", "cartesian plots"),
                 ("lat", "lon", "WGS-84 plots"))  # fmt: skip
        present = [
            p for p in pairs if getattr(self, p[0]) is not None or getattr(self, p[1]) is not None
        ]
        if len(present) > 1:
            raise ValueError(
                "a batch carries one geometry (range/azimuth, x/y or lat/lon), not both "
                + " and ".join(f"{a}/{b}" for a, b, _ in present)
            )
        if n > 0 and not present:
            raise ValueError(
                "plots need range and azimuth (radar), x and y (cartesian sensor) or lat and "
                "lon (WGS-84 sensor)"
            )
        for a, b, what in present:
            if getattr(self, a) is None or getattr(self, b) is None:
                missing = a if getattr(self, a) is None else b
                raise ValueError(f"column {missing!r} is missing: {what} need {a} and {b}")

    def _check_secondary(self) -> None:
        """The bounded secondary-surveillance columns (null allowed; NaN and inf were
        rejected by the field types) and the callsigns."""
        for name, lo, hi, hi_open, unit in _SSR_RANGES:
            values = getattr(self, name)
            if values is not None:
                col.check_nullable_range(name, values, lo, hi, hi_open=hi_open, unit=unit)
        if self.callsign is not None:
            col.check_strings("callsign", self.callsign, ident.CALLSIGN_RE,
                              "1-8 characters A-Z, 0-9 and inner spaces")  # fmt: skip

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
        """Return a column as a NumPy array, or None: float64 (NaN for null), int64 for
        time/target_id and the codes (mode_s, mode_3a, flight_status: -1 for null), bool
        for the flags (false for null), str for callsign ("" for null). The array is
        read-only and shared by every call (copy it to modify it)."""
        values = getattr(self, name)
        if values is None:
            return None
        arrays = self.__pydantic_private__.get("_arrays")
        kept = None if arrays is None else arrays.get(name)
        if kept is not None and kept[0] is values and len(kept[1]) == len(values):
            return kept[1]
        if name in _INT_COLUMNS:
            if name in ("time", "target_id"):
                arr = np.asarray(values, dtype=np.int64)
            else:
                arr = np.asarray([-1 if v is None else v for v in values], dtype=np.int64)
        elif name in FLAG_COLUMNS:
            arr = np.asarray([bool(v) for v in values], dtype=bool)
        elif name == "callsign":
            arr = np.asarray(["" if v is None else v for v in values], dtype="<U8")
        else:
            arr = np.asarray(values, dtype=np.float64)
        return self._keep(name, arr)

    def validated_column(self, name: str) -> np.ndarray | None:
        """``mode_3a`` (-1) or ``flight_level`` (NaN) without the replies flagged not
        validated or garbled: the values to trust as an identity or a level."""
        arr = self.column(name)
        if arr is None:
            return None
        bad = np.zeros(len(arr), bool)
        for flag in (f"{name}_not_validated", f"{name}_garbled"):
            f = self.column(flag)
            if f is not None:
                bad |= f
        if not bad.any():
            return arr
        out = arr.copy()
        out[bad] = -1 if arr.dtype.kind == "i" else np.nan
        return out
