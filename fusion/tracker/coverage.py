"""Which tracks a batch could have detected, and when (multi-radar coverage).

A track whose lazily predicted position x̂ + v̂ dt lies inside the batch's range/sector
(:class:`fusion.tracker.measurements.SectorCoverage`) within ``coverage_sigma`` σ, with
σ² = tr P_pos + tr P_vel dt², is predicted to its illumination time (the sector's sweep
time at its azimuth) and updated; the others are left untouched. Times in ns.

Detection share: a selected track's detection probability in the batch is
P_D · P_sector · P_range · P_cone (eqs. C2-C4 of :mod:`.measurements`: the probability,
under its predicted Gaussian, that the track was in the swept sector, in range and
below the radar's maximum elevation e_max, with the height of its last plot). A missed
detection where the radar could not see the track then does not erode its existence
(P_D → 0 gives δ_k → 0 in [thesis] (2.39), and (2.41) ψ_{k|k} → ψ_{k|k−1}), and a track
whose uncertainty straddles several sectors is not eroded once per sector.

Blind tracks: a track with P_cone below ``blind_share`` is in the cone of silence. It is
not predicted or updated by that batch (it coasts lazily, as outside the coverage), and
its ``max_coast`` clock restarts: a known gap, an aircraft in the cone comes out of it,
unlike one that left the coverage, whose clock keeps running. Its existence is held
over the blind time too (:func:`existence_clock`): the Markov chain ([thesis] (5.3))
predicts ψ only from the later of the track's last prediction and its last blind batch.
With Δ11 = 0.98 per second a 100 s crossing of the cone would otherwise leave
ψ ≤ 0.98¹⁰⁰ ≈ 0.13 at the exit, and the first misses at the cone's edge terminate the
track before the aircraft is seen again.

Plot timing (``coverage.timing = "plots"``: report-based sensors, a surface radar whose
sweep phase is unknown): a track's time in the batch is the time of the batch's plot
nearest to its lazily predicted position when that plot lies within
``coverage_sigma`` · √(σ² + r²) + |v̂| Δ (r² the plots' largest per-axis variance, Δ the
batch's time span: how far the track moves across it), else the batch time. A track
updated by its own report is so predicted to that report's time (1-s batches of reports
at their own times; the out-of-sequence update when that time is before the track's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .measurements import MeasurementBatch

NS = 1e-9


@dataclass
class CoverageView:
    """Every track seen from one batch: inside (n,) whether its lazily predicted position
    is in the batch's coverage within ``coverage_sigma`` σ; t_pred (n,) ns its
    prediction time (the sweep time at its position, not before its own time); t_sweep
    (n,) ns the sweep time itself (the batch time without a sweep; not clipped: the
    out-of-sequence split compares it with the track's time); p (n, k) the predicted
    positions x̂ + v̂ dt, m; var (n,) σ² = tr P_pos + tr P_vel dt², m²; polar: their
    (range m, azimuth rad) from the site (None without a coverage)."""

    inside: np.ndarray
    t_pred: np.ndarray
    t_sweep: np.ndarray
    p: np.ndarray | None = None
    var: np.ndarray | None = None
    polar: tuple[np.ndarray, np.ndarray] | None = None


def detection_share(
    batch: MeasurementBatch, view: CoverageView, rows: np.ndarray, height: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(P_sector · P_range, P_cone) (len(rows),) of the tracks ``rows`` at the batch
    time, eqs. (C2)-(C4) of :mod:`.measurements`, with the per-axis σ of the lazily
    predicted position (σ² = (tr P_pos + tr P_vel dt²)/2) and their heights ``height``;
    ones without a coverage."""
    n = len(rows)
    if batch.coverage is None or n == 0:
        return np.ones(n), np.ones(n)
    sigma = np.sqrt(0.5 * view.var[rows])
    polar = (view.polar[0][rows], view.polar[1][rows])
    return batch.coverage.detection_share(view.p[rows], sigma, height, polar)


def existence_clock(t_last: np.ndarray, coast_from: np.ndarray) -> np.ndarray:
    """The time (n,) ns from which each track's existence chain predicts: the later of its
    last prediction ``t_last`` and the last batch that found it blind (``coast_from``,
    or its last plot); the chain does not act in a cone of silence (module docstring)."""
    return np.maximum(t_last, coast_from)


def track_heights(
    height: np.ndarray, assigned: np.ndarray, plot_heights: np.ndarray | None
) -> np.ndarray:
    """The tracks' heights (n,) after a batch: the height of each track's most likely
    plot (``assigned`` (n,) plot index, −1 none) where known, else the previous one."""
    if plot_heights is None or len(plot_heights) == 0:
        return height
    rows = np.flatnonzero(assigned >= 0)
    h = np.asarray(plot_heights, dtype=np.float64)[assigned[rows]]
    ok = np.isfinite(h)
    out = height.copy()
    out[rows[ok]] = h[ok]
    return out


def select_tracks(
    batch: MeasurementBatch,
    x: np.ndarray,
    P: np.ndarray,
    t_last: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    coverage_sigma: float,
) -> CoverageView:
    """The :class:`CoverageView` of track estimates x (n, d), P (n, d, d) at times
    t_last (n,) ns; pos/vel: the position and velocity indices."""
    n = len(t_last)
    t = np.full(n, batch.time_ns, dtype=np.int64)
    if batch.coverage is None or n == 0:
        return CoverageView(np.ones(n, bool), np.maximum(t, t_last), t)
    cov = batch.coverage
    dt = np.maximum(batch.time_ns - t_last, 0) * NS
    p = x[:, pos] + x[:, vel] * dt[:, None]
    var = P[:, pos, pos].sum(axis=1) + P[:, vel, vel].sum(axis=1) * dt**2
    polar = cov.polar(p)  # once for every test
    inside = cov.contains(p, coverage_sigma * np.sqrt(var), polar)
    if cov.timing == "plots":
        t = nearest_plot_times(batch, p, var, np.hypot(*x[:, vel].T[:2]), coverage_sigma)
    elif cov.time_end > cov.time_start:
        t = cov.illumination_time(p, polar)
    return CoverageView(inside, np.maximum(t, t_last), t, p, var, polar)


def nearest_plot_times(
    batch: MeasurementBatch, p: np.ndarray, var: np.ndarray, speed: np.ndarray, k: float
) -> np.ndarray:
    """(n,) ns: the time of the plot nearest to each predicted position p (n, ≥2) within
    k √(var + r²) + speed Δ (module docstring), else the batch time."""
    n = len(p)
    t = np.full(n, batch.time_ns, dtype=np.int64)
    if len(batch) == 0 or n == 0 or batch.plot_times is None:
        return t
    axes = list(batch.coverage.axes)
    z = np.asarray(batch.z, dtype=np.float64)
    times = np.asarray(batch.plot_times, dtype=np.int64)
    R = np.asarray(batch.R, dtype=np.float64).reshape(len(z), z.shape[1], z.shape[1])
    r2 = float(np.max(np.trace(R[:, :2, :2], axis1=1, axis2=2))) / 2.0
    span = max(batch.time_ns - int(times.min()), 0) * NS
    dist, idx = cKDTree(z[:, axes]).query(p[:, axes])
    near = dist <= k * np.sqrt(var + r2) + speed * span
    t[near] = times[idx[near]]
    return t
