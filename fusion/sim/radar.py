"""A rotating-antenna polar radar (2d or 3d): beam-crossing plot times, detection, polar
Gaussian noise and Poisson clutter for one antenna revolution.

The antenna turns clockwise at a constant rate: during scan k (window [t_k, t_k + T))
the beam points at azimuth θ(t) = 2π (t − t_k)/T, north at t_k. A target at azimuth
φ(t) (clockwise from true north at the site, from ``pymap3d.geodetic2aer``) is hit when
θ(t) = φ(t); the crossing time is the fixed point t = t_k + T φ(t)/2π, found by
iterating from t_k (a contraction with ratio ≈ φ̇T/2π ≪ 1; stop at 1e-7 s). A solution
that does not converge (a target sitting on north while the beam wraps) or that falls
outside the window is not a crossing of this scan: rare, and then at most one plot of
that target is lost.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pymap3d

from .identity import reply_columns
from .scan import ScanData
from .sensor import AnnulusRegion, SensorConfig
from .trajectories import TargetSet

TWO_PI = 2.0 * math.pi

Locate = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""(target index, time s) → (lat deg, lon deg, height above the ellipsoid m)."""


def wrap_azimuth(a: np.ndarray) -> np.ndarray:
    """Wrap angles into [0, 2π) (guarding the float case mod → exactly 2π)."""
    a = np.mod(a, TWO_PI)
    a[a >= TWO_PI] = 0.0
    return a


def site_aer(
    cfg: SensorConfig, lat: np.ndarray, lon: np.ndarray, alt: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth (rad, clockwise from true north, [0, 2π)), elevation (rad) and slant range
    (m) of points seen from the radar site (WGS-84, geometric line of sight)."""
    s = cfg.site
    az, el, rng = pymap3d.geodetic2aer(lat, lon, alt, s.lat, s.lon, s.alt, deg=True)
    return wrap_azimuth(np.radians(np.asarray(az, float))), np.radians(el), np.asarray(rng)


def beam_crossing_times(
    cfg: SensorConfig, t_start: float, index: np.ndarray, locate: Locate, *, max_iter: int = 8
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Solve the beam crossing of targets ``index`` in the scan starting at ``t_start`` (s).

    Returns (t, azimuth, elevation, slant range, converged) at the crossing."""
    period = cfg.site.scan_period
    t = np.full(index.shape, float(t_start))
    for _ in range(max_iter):
        az, el, r = site_aer(cfg, *locate(index, t))
        t_new = t_start + period * az / TWO_PI
        step = np.abs(t_new - t)
        t = t_new
        if step.size == 0 or step.max() < 1e-7:
            break
    az, el, r = site_aer(cfg, *locate(index, t))
    beam = TWO_PI * (t - t_start) / period
    resid = np.abs((az - beam + math.pi) % TWO_PI - math.pi)
    converged = resid < 1e-6
    return t, az, el, r, converged


def _target_plots(cfg: SensorConfig, t0: float, targets: TargetSet, locate: Locate, rng):
    """Detected target plots of the scan starting at t0 (s): (time s, target id, range m,
    azimuth rad, elevation rad or altitude m, target index, true height m), biased then
    noisy."""
    site = cfg.site
    t1 = t0 + site.scan_period
    three_d = site.kind == "3d"
    cand = np.flatnonzero((targets.t_birth < t1) & (targets.t_death > t0))
    u_det = rng.random(cand.size)
    noise = rng.standard_normal((cand.size, 3))
    if cand.size:
        t, az, el, r, conv = beam_crossing_times(cfg, t0, cand, locate)
        _, _, alt = locate(cand, t)
        ok = (
            conv
            & (t >= t0)
            & (t < t1)
            & targets.alive(t, cand)
            & (r >= site.min_range)
            & (r <= site.max_range)
            & (el >= cfg.min_elevation)
            & (u_det < site.p_detection)
        )
    else:
        t = az = el = r = alt = np.zeros(0)
        ok = np.zeros(0, bool)
    tt = t[ok]
    tid = targets.target_id[cand[ok]]
    n_ok = noise[ok]
    # systematic errors (fusion.frames.sensor_bias eq. 1), then the random noise
    r_b, az_b, _ = cfg.bias.distort(r[ok], az[ok], np.zeros(0, np.int64))
    rr = np.maximum(r_b + site.sigma_range * n_ok[:, 0], 0.0)
    aa = wrap_azimuth(az_b + site.sigma_azimuth * n_ok[:, 1])
    if three_d:
        third = np.clip(el[ok] + site.sigma_elevation * n_ok[:, 2], -math.pi / 2, math.pi / 2)
    else:
        third = alt[ok] + site.sigma_altitude * n_ok[:, 2]
        if cfg.altitude_quantum > 0.0:
            third = np.round(third / cfg.altitude_quantum) * cfg.altitude_quantum
        third = np.clip(third, -1000.0, 100_000.0)

    return tt, tid, rr, aa, third, cand[ok], alt[ok]


def _clutter(cfg: SensorConfig, t0: float, rng: np.random.Generator):
    """Poisson clutter of one scan: (range m, azimuth rad, time s, elevation or altitude)
    over the coverage annulus and ``cfg.regions``, uniform in area."""
    site = cfg.site
    regions = [AnnulusRegion(site.min_range, site.max_range, 0.0, TWO_PI, site.clutter_density)]
    regions.extend(cfg.regions)
    samples = [reg.sample(rng) for reg in regions]
    cr = np.concatenate([s[0] for s in samples])
    ca = np.concatenate([s[1] for s in samples])
    ct = t0 + site.scan_period * ca / TWO_PI
    if site.kind == "3d":
        cthird = rng.uniform(0.0, cfg.clutter_max_elevation, cr.size)
    else:
        cthird = rng.uniform(0.0, cfg.clutter_max_altitude, cr.size)
        if cfg.altitude_quantum > 0.0:
            cthird = np.round(cthird / cfg.altitude_quantum) * cfg.altitude_quantum
    return cr, ca, ct, cthird


def radar_scan(
    cfg: SensorConfig,
    k: int,
    targets: TargetSet,
    locate: Locate,
    rng: np.random.Generator,
    start_time_ns: int,
    radar_index: int = 0,
    identity_rng: np.random.Generator | None = None,
) -> ScanData:
    """Plots of scan ``k`` of a 2d/3d radar (see module docstring for the geometry).

    Target plots: detected with probability ``site.p_detection`` when alive at the
    crossing, within [min_range, max_range] (slant) and at or above ``min_elevation``;
    range + N(0, σ_range²), azimuth + N(0, σ_azimuth²) wrapped into [0, 2π), 3d:
    elevation + N(0, σ_elevation²); 2d: altitude = true height + N(0, σ_altitude²),
    quantised to ``altitude_quantum``. Clutter: Poisson with ``site.clutter_density`` per
    m² per scan over the annulus [min_range, max_range] plus ``cfg.regions``, uniform in
    area; its time is when the beam passes its azimuth. Random draws per scan are in a
    fixed order, so a seeded generator reproduces the scan exactly.

    Systematic errors ``cfg.bias`` (:class:`fusion.frames.sensor_bias.SensorBias`, eq. 1)
    act on the target plots' true range and azimuth before the noise; the time offset
    shifts every reported time of the radar (plots, sector bounds), so the plot of a
    target seen at true time t carries the time t + b_t.

    With ``cfg.report_mode_s`` the target plots carry their aircraft's codes; with an
    ``identity_rng`` (the sensor's own stream for replies, so the plots above do not
    change) also the other secondary-surveillance columns (:mod:`fusion.sim.identity`:
    the code at the plot time, flight level, callsign, garbled replies, downlinked
    parameters)."""
    site = cfg.site
    period = site.scan_period
    t0 = cfg.scan_time(k)
    three_d = site.kind == "3d"

    tt, tid, rr, aa, third, cand_ok, height = _target_plots(cfg, t0, targets, locate, rng)
    cr, ca, ct, cthird = _clutter(cfg, t0, rng)

    time_s = np.concatenate([tt, ct])
    # the radar's clock runs cfg.bias.time ahead: every time it reports is shifted
    start_time_ns = start_time_ns + cfg.bias.time_ns
    time_ns = start_time_ns + np.rint(time_s * 1e9).astype(np.int64)
    order = np.argsort(time_ns, kind="stable")
    bounds = start_time_ns + np.rint(
        (t0 + period * np.arange(site.n_sectors + 1) / site.n_sectors) * 1e9
    ).astype(np.int64)
    time_ns = time_ns[order]
    sector = np.clip(np.searchsorted(bounds, time_ns, side="right") - 1, 0, site.n_sectors - 1)
    target_id = np.concatenate([tid, np.full(cr.size, -1, np.int64)])[order]
    third_all = np.concatenate([third, cthird])[order]
    mode_s = mode_3a = secondary = None
    if cfg.report_mode_s:
        mode_s = np.concatenate([targets.mode_s[cand_ok], np.full(cr.size, -1)])[order]
        mode_3a = np.concatenate([targets.mode_3a[cand_ok], np.full(cr.size, -1)])[order]
        if identity_rng is not None:
            reported = height if three_d else third
            secondary = _secondary(cfg, targets, cand_ok, tt, reported, locate, identity_rng,
                                   cr.size, order)  # fmt: skip
            mode_3a = secondary.pop("mode_3a")
            third_all = _drop_garbled_levels(third_all, secondary, three_d)
    return ScanData(
        radar_id=site.radar_id,
        radar_index=radar_index,
        kind=str(site.kind),
        scan=k,
        time_start=int(bounds[0]),
        time_end=int(bounds[-1]),
        sector_bounds=bounds,
        time=time_ns,
        target_id=target_id.astype(np.int64),
        sector=sector.astype(np.int64),
        range=np.concatenate([rr, cr])[order],
        azimuth=np.concatenate([aa, ca])[order],
        elevation=third_all if three_d else None,
        altitude=None if three_d else third_all,
        mode_s=None if mode_s is None else mode_s.astype(np.int64),
        mode_3a=None if mode_3a is None else mode_3a.astype(np.int64),
        secondary=secondary,
    )


def _drop_garbled_levels(third: np.ndarray, secondary: dict, three_d: bool) -> np.ndarray:
    """A 2-D radar's plot whose Mode C reply is garbled has no altitude (NaN), as the
    ASTERIX reader leaves it; a 3-D radar's elevation is not from the reply."""
    if three_d:
        return third
    return np.where(secondary["flight_level_garbled"], np.nan, third)


def _secondary(cfg, targets, index, t, height, locate, rng, n_clutter, order) -> dict:
    """The replies' secondary-surveillance columns of the target plots (none for the
    clutter after them), in plot order."""
    cols = reply_columns(targets, index, t, height, locate, rng, cfg.garble_probability)
    out = {}
    for name, v in cols.items():
        fill = {"b": False, "i": -1, "O": ""}.get(v.dtype.kind, np.nan)
        out[name] = np.concatenate([v, np.full(n_clutter, fill, v.dtype)])[order]
    return out
