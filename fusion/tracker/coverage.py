"""Which tracks a batch could have detected, and when (multi-radar coverage).

A track whose lazily predicted position x̂ + v̂ dt lies inside the batch's range/sector
(:class:`fusion.tracker.measurements.SectorCoverage`) within ``coverage_sigma`` σ, with
σ² = tr P_pos + tr P_vel dt², is predicted to its illumination time (the sector's sweep
time at its azimuth) and updated; the others are left untouched. Times in ns.
"""

from __future__ import annotations

import numpy as np

from .measurements import MeasurementBatch

NS = 1e-9


def select_tracks(
    batch: MeasurementBatch,
    x: np.ndarray,
    P: np.ndarray,
    t_last: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    coverage_sigma: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(inside (n,) bool, prediction time (n,) ns) for track estimates x (n, d), P
    (n, d, d) at times t_last (n,) ns; pos/vel: the position and velocity indices."""
    n = len(t_last)
    t = np.full(n, batch.time_ns, dtype=np.int64)
    if batch.coverage is None or n == 0:
        return np.ones(n, bool), np.maximum(t, t_last)
    cov = batch.coverage
    dt = np.maximum(batch.time_ns - t_last, 0) * NS
    p = x[:, pos] + x[:, vel] * dt[:, None]
    Ppos = P[:, pos, pos].sum(axis=1)
    Pvel = P[:, vel, vel].sum(axis=1)
    sigma = np.sqrt(Ppos + Pvel * dt**2)
    inside = cov.contains(p, coverage_sigma * sigma)
    if cov.time_end > cov.time_start:
        t = cov.illumination_time(p)
    return inside, np.maximum(t, t_last)
