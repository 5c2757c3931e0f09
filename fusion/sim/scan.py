"""``ScanData``: one sensor scan as plain NumPy columns (the simulator's fast path).

Monte Carlo code consumes these directly (no pydantic); the simulator's message path
(:meth:`fusion.sim.Simulator.run`) cuts the same arrays into sector ``PlotBatch``es, so
both paths carry identical numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REPORT_COLUMNS = ("lat", "lon", "sigma", "v_east", "v_north", "sigma_velocity")
"""The columns of report sensors (besides x/y and altitude)."""


@dataclass
class ScanData:
    """Plots of one antenna revolution (polar radars) or one snapshot (cartesian sensor).

    Times are integer ns UTC. Columns have one entry per plot, sorted by time.
    ``sector_bounds`` (n_sectors + 1,) holds the ns times at which the beam crosses the
    sector boundaries (azimuth j·2π/n_sectors clockwise from north) during this scan;
    ``sector`` is each plot's sector index. Polar radars fill ``range`` (m, slant),
    ``azimuth`` (rad clockwise from north, [0, 2π)) and ``elevation`` (3d, rad) or
    ``altitude`` (2d, m); the cartesian sensor fills ``x``/``y`` (m, scenario plane), a
    multilateration ``x``/``y`` (m, east/north of its reference point) and ``altitude``,
    ADS-B ``lat``/``lon`` (deg) and ``altitude``; report sensors (:mod:`fusion.sim.reports`)
    also ``sigma`` (m per axis), ADS-B ``v_east``/``v_north``/``sigma_velocity`` (m/s).
    ``target_id`` is the originating target, -1 for clutter. ``mode_s``/``mode_3a`` use -1
    for "none"; ``secondary`` holds the other secondary-surveillance columns of
    :mod:`schemas.identity` (NaN, "" or False for none; :mod:`fusion.sim.identity`)."""

    radar_id: str
    radar_index: int
    kind: str
    scan: int
    time_start: int
    time_end: int
    sector_bounds: np.ndarray
    time: np.ndarray
    target_id: np.ndarray
    sector: np.ndarray
    range: np.ndarray | None = None
    azimuth: np.ndarray | None = None
    elevation: np.ndarray | None = None
    altitude: np.ndarray | None = None
    x: np.ndarray | None = None
    y: np.ndarray | None = None
    lat: np.ndarray | None = None
    lon: np.ndarray | None = None
    sigma: np.ndarray | None = None
    v_east: np.ndarray | None = None
    v_north: np.ndarray | None = None
    sigma_velocity: np.ndarray | None = None
    mode_s: np.ndarray | None = None
    mode_3a: np.ndarray | None = None
    secondary: dict[str, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self.time)

    @property
    def n_sectors(self) -> int:
        return len(self.sector_bounds) - 1

    @property
    def z(self) -> np.ndarray:
        """Measurement vectors: (m, 2) [x, y] for cartesian sensors, [lat, lon] for ADS-B,
        (m, 3) [range, azimuth, elevation] for 3d and (m, 2) [range, azimuth] for 2d radars."""
        if self.lat is not None:
            return np.column_stack([self.lat, self.lon])
        if self.x is not None:
            return np.column_stack([self.x, self.y])
        if self.elevation is not None:
            return np.column_stack([self.range, self.azimuth, self.elevation])
        return np.column_stack([self.range, self.azimuth])

    @property
    def time_s(self) -> np.ndarray:
        """Plot times as float seconds relative to ``time_start``."""
        return (self.time - self.time_start) * 1e-9

    def select(self, mask: np.ndarray) -> ScanData:
        """A copy with only the plots where ``mask`` is true (same scan metadata)."""
        cols = {}
        for name in (
            "time", "target_id", "sector", "range", "azimuth", "elevation", "altitude",
            "x", "y", *REPORT_COLUMNS, "mode_s", "mode_3a",
        ):  # fmt: skip
            v = getattr(self, name)
            cols[name] = None if v is None else v[mask]
        if self.secondary is not None:
            cols["secondary"] = {k: v[mask] for k, v in self.secondary.items()}
        return ScanData(
            radar_id=self.radar_id,
            radar_index=self.radar_index,
            kind=self.kind,
            scan=self.scan,
            time_start=self.time_start,
            time_end=self.time_end,
            sector_bounds=self.sector_bounds,
            **cols,
        )
