"""Simulation-side description of one sensor: its wire ``RadarSite`` plus what only the
simulator needs (antenna phase, horizon, clutter regions, coverage of the planar sensor,
what a report sensor reports).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from skyfuse.fusion.frames.sensor_bias import SensorBias
from skyfuse.schemas import RadarSite
from skyfuse.schemas.adsb_quality import position_sigma_nacp, velocity_sigma

FT = 0.3048


@dataclass(frozen=True)
class RectRegion:
    """Axis-aligned rectangle in the scenario plane (m) with a Poisson clutter density
    (expected false plots per m² per scan)."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    density: float

    def __post_init__(self) -> None:
        if not (self.x_max > self.x_min and self.y_max > self.y_min):
            raise ValueError(f"clutter rectangle {self} has no area")
        if not (math.isfinite(self.density) and self.density >= 0.0):
            raise ValueError(f"clutter density = {self.density}: must be finite and >= 0")

    @property
    def area(self) -> float:
        """m²"""
        return (self.x_max - self.x_min) * (self.y_max - self.y_min)

    def density_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The region's clutter density (m⁻² per scan) at points (x, y) in m: ``density``
        inside the half-open rectangle [x_min, x_max) × [y_min, y_max), else 0 (so two
        rectangles that share an edge never both count a point on it)."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        inside = (x >= self.x_min) & (x < self.x_max) & (y >= self.y_min) & (y < self.y_max)
        return np.where(inside, self.density, 0.0)

    def sample(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Poisson(density × area) points uniform over the rectangle: (x, y) in m."""
        n = rng.poisson(self.density * self.area)
        x = rng.uniform(self.x_min, self.x_max, n)
        y = rng.uniform(self.y_min, self.y_max, n)
        return x, y


@dataclass(frozen=True)
class AnnulusRegion:
    """Annular sector around a polar radar: range in [r_min, r_max] m, azimuth from
    ``az_start`` clockwise over ``az_width`` rad; Poisson density per m² per scan (area
    measured with the slant range as the radius)."""

    r_min: float
    r_max: float
    az_start: float
    az_width: float
    density: float

    def __post_init__(self) -> None:
        if not (0.0 <= self.r_min < self.r_max):
            raise ValueError(f"annulus r_min={self.r_min}, r_max={self.r_max}: need 0<=min<max")
        if not (0.0 < self.az_width <= 2 * math.pi):
            raise ValueError(f"annulus az_width = {self.az_width}: must be in (0, 2π]")
        if not (math.isfinite(self.density) and self.density >= 0.0):
            raise ValueError(f"clutter density = {self.density}: must be finite and >= 0")

    @property
    def area(self) -> float:
        """m²"""
        return 0.5 * self.az_width * (self.r_max**2 - self.r_min**2)

    def sample(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Poisson(density × area) points uniform in area: (range m, azimuth rad [0, 2π))."""
        n = rng.poisson(self.density * self.area)
        r = np.sqrt(rng.uniform(self.r_min**2, self.r_max**2, n))
        az = np.mod(self.az_start + rng.uniform(0.0, self.az_width, n), 2 * math.pi)
        az[az >= 2 * math.pi] = 0.0
        return r, az


@dataclass(frozen=True)
class ReportModel:
    """What a report sensor reports (:mod:`fusion.sim.reports`): the share of the Mode-S aircraft
    equipped (ADS-B), the NACp of their positions (a share ``poor_fraction`` with
    ``poor_nacp``), the NACv of their velocities (0: none) and the altitude step, m."""

    equipped_fraction: float = 1.0
    nacp: int = 9
    poor_fraction: float = 0.0
    poor_nacp: int = 6
    nac_v: int = 2
    altitude_quantum: float = 25 * FT

    def __post_init__(self) -> None:
        for name in ("equipped_fraction", "poor_fraction"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} = {getattr(self, name)}: must be in [0, 1]")
        for name in ("nacp", "poor_nacp"):
            if position_sigma_nacp(getattr(self, name)) is None:
                raise ValueError(f"{name} = {getattr(self, name)}: must be a NACp in 1..11")
        if self.nac_v != 0 and velocity_sigma(self.nac_v) is None:
            raise ValueError(f"nac_v = {self.nac_v}: must be 0 (no velocity) or 1..4")
        if self.altitude_quantum < 0.0:
            raise ValueError(f"altitude_quantum = {self.altitude_quantum}: must be >= 0 m")


@dataclass
class SensorConfig:
    """One simulated sensor.

    * ``phase``: seconds after the scenario start at which scan 0 begins (the beam points
      north); scan k covers [phase + kT, phase + (k+1)T). For the cartesian sensor scan k
      is a snapshot at ``phase + k T`` and scans start at ``first_scan``.
    * ``min_elevation``: plots only from targets at or above this elevation (rad, geometric,
      no refraction); −π/2 disables the horizon test.
    * ``altitude_quantum``: 2d radars quantise the reported altitude to this step (m),
      e.g. 25 ft = 7.62 m; 0 = no quantisation.
    * ``clutter_max_elevation`` (3d, rad) / ``clutter_max_altitude`` (2d, m): false plots
      get an elevation/altitude uniform in [0, max].
    * ``regions``: extra clutter (``AnnulusRegion`` for polar, ``RectRegion`` for cartesian).
    * ``coverage``: cartesian sensor only, (x_min, x_max, y_min, y_max) m of the uniform
      clutter at ``site.clutter_density``.
    * ``report_mode_s``: fill the mode_s / mode_3a columns (from the targets' codes) and
      the other secondary-surveillance columns (:mod:`fusion.sim.identity`).
    * ``garble_probability``: the share of replies whose code, or flight level, is garbled.
    * ``bias``: the radar's systematic errors (polar radars; truth for registration,
      never told to the tracker).
    * ``report``: a report sensor's (``site.detection = reports``: ADS-B, multilateration)
      equipage, quality and altitude step (:mod:`fusion.sim.reports`); its cycle k covers
      [phase + kT, phase + (k+1)T), like a radar's scan.
    """

    site: RadarSite
    phase: float = 0.0
    first_scan: int = 0
    min_elevation: float = -math.pi / 2
    altitude_quantum: float = 0.0
    clutter_max_elevation: float = math.radians(2.0)
    clutter_max_altitude: float = 3000.0
    regions: tuple = field(default_factory=tuple)
    coverage: tuple[float, float, float, float] | None = None
    report_mode_s: bool = False
    garble_probability: float = 0.0
    bias: SensorBias = field(default_factory=SensorBias)
    report: ReportModel = field(default_factory=ReportModel)

    @property
    def reports(self) -> bool:
        """A report sensor (:mod:`fusion.sim.reports`), not a sweeping one."""
        return self.site.detection == "reports"

    def __post_init__(self) -> None:
        if self.reports:
            if (
                self.regions
                or not self.bias.is_zero
                or self.site.kind not in ("cartesian", "wgs84")
            ):
                raise ValueError(
                    f"report sensor {self.site.radar_id}: a cartesian (multilateration) or "
                    "wgs84 (ADS-B) site without clutter regions or bias model"
                )
        elif self.site.kind == "cartesian":
            if self.coverage is None:
                raise ValueError(f"cartesian sensor {self.site.radar_id}: coverage is required")
            x0, x1, y0, y1 = self.coverage
            if not (x1 > x0 and y1 > y0):
                raise ValueError(f"coverage {self.coverage} has no area")
            for r in self.regions:
                if not isinstance(r, RectRegion):
                    raise ValueError("cartesian sensors take RectRegion clutter regions")
            if not self.bias.is_zero:
                raise ValueError(f"cartesian sensor {self.site.radar_id}: no bias model")
        else:
            for r in self.regions:
                if not isinstance(r, AnnulusRegion):
                    raise ValueError("polar radars take AnnulusRegion clutter regions")
        if self.phase < 0.0:
            raise ValueError(f"phase = {self.phase}: must be >= 0 s")

    @property
    def radar_id(self) -> str:
        return self.site.radar_id

    def scan_time(self, k: int) -> float:
        """Start of scan k (polar) / snapshot time of scan k (cartesian), s after start."""
        return self.phase + k * self.site.scan_period

    def scans_in(self, duration: float) -> range:
        """Scan numbers whose window (polar) or snapshot (cartesian) ends by ``duration``."""
        t_period = self.site.scan_period
        eps = 1e-9 * max(1.0, duration)
        if self.site.kind == "cartesian" and not self.reports:
            last = math.floor((duration - self.phase) / t_period + eps)
            return range(self.first_scan, max(last + 1, self.first_scan))
        n = math.floor((duration - self.phase) / t_period + eps)
        return range(0, max(n, 0))
