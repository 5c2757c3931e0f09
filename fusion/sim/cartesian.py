"""The planar cartesian test sensor of the thesis scenarios ([thesis] §7.3-7.4, [LM-IPF] eq. 20-21):
z = H x + w, H picks (x, y), w ~ N(0, σ² I) (R = 25 I m² for σ = 5 m), one snapshot per
scan at the scan time, detection probability P_D, Poisson clutter uniform over the
coverage rectangle and over density rectangles."""

from __future__ import annotations

import numpy as np

from .scan import ScanData
from .sensor import RectRegion, SensorConfig
from .trajectories import TargetSet


def clutter_regions(cfg: SensorConfig) -> list[RectRegion]:
    """The sensor's clutter rectangles: its coverage at ``site.clutter_density`` and its
    extra ``regions``; densities add where they overlap."""
    x0, x1, y0, y1 = cfg.coverage
    return [RectRegion(x0, x1, y0, y1, cfg.site.clutter_density), *cfg.regions]


def clutter_density_at(cfg: SensorConfig, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The true clutter density (expected false plots per m² per scan) at points (x, y) m:
    the sum over :func:`clutter_regions` of each rectangle's density where it contains the
    point. It is what a known-clutter tracker (``clutter = "known"``) is told per plot."""
    total = np.zeros(np.broadcast(np.asarray(x), np.asarray(y)).shape)
    for reg in clutter_regions(cfg):
        total = total + reg.density_at(x, y)
    return total


def cartesian_scan(
    cfg: SensorConfig,
    k: int,
    targets: TargetSet,
    rng: np.random.Generator,
    start_time_ns: int,
    radar_index: int = 0,
    truth: tuple[np.ndarray, np.ndarray] | None = None,
) -> ScanData:
    """Plots of scan ``k`` (all at time ``cfg.scan_time(k)``), in random order so the
    order never reveals which plot is a target. x/y in m in the scenario plane.

    ``truth`` optionally gives the precomputed (alive mask (n,), positions (n, 3)) of all
    targets at the scan time (the simulator computes all scans at once)."""
    site = cfg.site
    t = cfg.scan_time(k)
    if truth is None:
        alive_all = targets.alive(t)
        idx = np.flatnonzero(alive_all)
        pos, _ = targets.state(t, idx)
    else:
        alive_all, pos_all = truth
        idx = np.flatnonzero(alive_all)
        pos = pos_all[idx]
    u_det = rng.random(idx.size)
    noise = rng.standard_normal((idx.size, 2))
    det = u_det < site.p_detection
    tx = pos[det, 0] + site.sigma_cartesian * noise[det, 0]
    ty = pos[det, 1] + site.sigma_cartesian * noise[det, 1]
    regions = clutter_regions(cfg)
    samples = [reg.sample(rng) for reg in regions]
    cx = np.concatenate([s[0] for s in samples])
    cy = np.concatenate([s[1] for s in samples])
    x = np.concatenate([tx, cx])
    y = np.concatenate([ty, cy])
    tid = np.concatenate([targets.target_id[idx[det]], np.full(cx.size, -1, np.int64)])
    perm = rng.permutation(x.size)
    t_ns = start_time_ns + int(np.rint(t * 1e9))
    return ScanData(
        radar_id=site.radar_id,
        radar_index=radar_index,
        kind="cartesian",
        scan=k,
        time_start=t_ns,
        time_end=t_ns,
        sector_bounds=np.array([t_ns, t_ns], np.int64),
        time=np.full(x.size, t_ns, np.int64),
        target_id=tid[perm].astype(np.int64),
        sector=np.zeros(x.size, np.int64),
        x=x[perm],
        y=y[perm],
    )
