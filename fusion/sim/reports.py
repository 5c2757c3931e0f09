"""Report-based sensors: ADS-B (``wgs84``) and multilateration (``cartesian``), each
reporting the aircraft it sees once per report cycle at the aircraft's own time, with no
sweep and no sectors (docs/concepts/sensors.md).

Per run (:func:`report_fleet`, the sensor's own stream): which aircraft the sensor can
report — a multilateration every aircraft with a transponder (a Mode-S address or a
Mode-3/A code), ADS-B a share ``equipped_fraction`` of the Mode-S aircraft (1090 MHz
extended squitter needs the 24-bit address; the others are *not equipped* and never
reported) — the phase φ_i ∈ U[0, T) of each aircraft's reports in the cycle T
(``site.scan_period``), and, for ADS-B, each aircraft's NACp: ``nacp``, or ``poor_nacp``
for a share ``poor_fraction`` of them.

Cycle k covers [t_k, t_k + T), t_k = phase + k T; aircraft i is reported at
t = t_k + φ_i when it is alive, inside the coverage (slant range in [min_range,
max_range] from the site, inside the ``coverage`` polygon — in the site's ENU plane —
and below ``max_altitude``) and detected (probability ``site.p_detection``). Errors:

* **ADS-B**: a circular Gaussian position error of σ_i per axis in the aircraft's own
  east/north, σ_i = EPU(NACp_i)/2.4477 (:mod:`schemas.adsb_quality`: the NACp's 95 %
  bound read as the Rayleigh 95 % radius), reported as lat/lon with ``sigma`` = σ_i; the
  velocity east/north + N(0, σ_v²), σ_v from ``nac_v`` (none with ``nac_v`` = 0);
* **multilateration**: x/y east/north of the reference point (the site) + N(0, σ(ρ)²)
  per axis, σ(ρ) = √(σ_c² + (g ρ)²) with σ_c = ``sigma_cartesian``, g =
  ``sigma_growth`` and ρ the aircraft's horizontal distance from the reference point
  (the system's geometry degrades away from its receivers), reported as ``sigma`` (the
  I500 of a real system).

Both report the height rounded to ``altitude_quantum`` (25 ft: a barometric altitude in
the simulator's ISA atmosphere), the aircraft's Mode-S address and Mode-3/A code, and
ADS-B its callsign. Random draws per cycle are in a fixed order, so a seeded generator
reproduces every cycle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d
from skyfuse.fusion.tracker.coverage_polygon import inside
from skyfuse.schemas.adsb_quality import position_sigma_nacp, velocity_sigma

from .identity import enu_kinematics
from .scan import ScanData
from .sensor import SensorConfig
from .trajectories import TargetSet


@dataclass(frozen=True)
class ReportFleet:
    """Per aircraft of one report sensor for a run: reported at all, phase in the cycle
    (s) and, for ADS-B, NACp and σ per axis (m; NaN for a multilateration)."""

    reported: np.ndarray
    phase: np.ndarray
    nacp: np.ndarray
    sigma: np.ndarray


def report_fleet(cfg: SensorConfig, targets: TargetSet, rng: np.random.Generator) -> ReportFleet:
    """Draw the per-run aircraft properties of report sensor ``cfg`` (module docstring)."""
    m = cfg.report
    n = len(targets)
    u_equip, u_phase, u_poor = rng.random((3, n))
    adsb = cfg.site.kind == "wgs84"
    if adsb:
        reported = (targets.mode_s >= 0) & (u_equip < m.equipped_fraction)
    else:
        reported = (targets.mode_s >= 0) | (targets.mode_3a >= 0)
    poor = u_poor < m.poor_fraction
    nacp = np.where(poor, m.poor_nacp, m.nacp) if adsb else np.full(n, -1)
    sigma = np.array([position_sigma_nacp(int(c)) for c in nacp]) if adsb else np.full(n, np.nan)
    return ReportFleet(reported, u_phase * cfg.site.scan_period, nacp, sigma)


def _covered(cfg: SensorConfig, e, n, u, h) -> np.ndarray:
    """Inside the site's range ring, polygon and ceiling (points in the site's ENU, m)."""
    site = cfg.site
    slant = np.sqrt(e**2 + n**2 + u**2)
    ok = (slant >= site.min_range) & (slant <= site.max_range)
    if site.max_altitude is not None:
        ok &= h <= site.max_altitude
    if site.coverage is not None and ok.any():
        lat, lon = np.array(site.coverage, float).T
        ve, vn, _ = pymap3d.geodetic2enu(lat, lon, site.alt, site.lat, site.lon, site.alt)
        ok &= inside(np.column_stack([e, n]), np.column_stack([ve, vn]))
    return ok


def _errors(cfg: SensorConfig, fleet: ReportFleet, idx, lat, lon, h, e, n, noise, locate, t):
    """The reported columns of aircraft ``idx`` (module docstring) from the true positions
    (lat/lon/h, site ENU e/n) and standard normal draws ``noise`` (k, 4)."""
    site, m = cfg.site, cfg.report
    q = m.altitude_quantum
    cols = {"altitude": np.round(h / q) * q if q > 0 else h.copy()}
    if site.kind == "wgs84":
        sig = fleet.sigma[idx]
        la, lo, _ = pymap3d.enu2geodetic(sig * noise[:, 0], sig * noise[:, 1], 0.0, lat, lon, h)
        cols.update(lat=np.asarray(la, float), lon=np.asarray(lo, float), sigma=sig)
        if m.nac_v:
            sv = velocity_sigma(m.nac_v)
            k = enu_kinematics(idx, t, locate)
            cols.update(v_east=k["ve"] + sv * noise[:, 2], v_north=k["vn"] + sv * noise[:, 3],
                        sigma_velocity=np.full(len(idx), sv))  # fmt: skip
    else:
        sig = np.hypot(site.sigma_cartesian, site.sigma_growth * np.hypot(e, n))
        cols.update(x=e + sig * noise[:, 0], y=n + sig * noise[:, 1], sigma=sig)
    return cols


def report_scan(
    cfg: SensorConfig,
    k: int,
    targets: TargetSet,
    locate,
    rng: np.random.Generator,
    start_time_ns: int,
    fleet: ReportFleet,
    radar_index: int = 0,
) -> ScanData:
    """The reports of cycle ``k`` (module docstring), in time order; ``locate`` maps
    (target index, time s) to (lat deg, lon deg, height m)."""
    site = cfg.site
    t0 = cfg.scan_time(k)
    idx = np.flatnonzero(fleet.reported)
    t = t0 + fleet.phase[idx]
    u_det = rng.random(idx.size)
    noise = rng.standard_normal((idx.size, 4))
    lat, lon, h = (np.asarray(a, float) for a in locate(idx, t))
    e, n, u = (np.asarray(a, float) for a in pymap3d.geodetic2enu(lat, lon, h, site.lat,
                                                                  site.lon, site.alt))  # fmt: skip
    seen = targets.alive(t, idx) & (u_det < site.p_detection) & _covered(cfg, e, n, u, h)
    order = np.flatnonzero(seen)[np.argsort(t[seen], kind="stable")]
    idx_o, t_o = idx[order], t[order]
    cols = _errors(cfg, fleet, idx_o, lat[order], lon[order], h[order], e[order], n[order],
                   noise[order], locate, t_o)  # fmt: skip
    bounds = start_time_ns + np.rint(np.array([t0, t0 + site.scan_period]) * 1e9).astype(np.int64)
    secondary = {"callsign": targets.callsign[idx_o]} if site.kind == "wgs84" else None
    return ScanData(
        radar_id=site.radar_id,
        radar_index=radar_index,
        kind=str(site.kind),
        scan=k,
        time_start=int(bounds[0]),
        time_end=int(bounds[1]),
        sector_bounds=bounds,
        time=start_time_ns + np.rint(t_o * 1e9).astype(np.int64),
        target_id=targets.target_id[idx_o].astype(np.int64),
        sector=np.zeros(len(idx_o), np.int64),
        mode_s=targets.mode_s[idx_o].astype(np.int64),
        mode_3a=targets.mode_3a[idx_o].astype(np.int64),
        secondary=secondary,
        **cols,
    )
